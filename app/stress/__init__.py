"""Robustness harnesses for the app layer (`storybeam stress`, tests/test_robust_*.py):
SIGKILL during story saves, bad database/package/calibration files, and the UI monkey.
"""
