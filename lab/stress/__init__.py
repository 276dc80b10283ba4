"""Robustness harnesses for the app layer (`storybeam stress`; their short versions run in tests/robust/):
fuzzed motion files (mutation fuzzing, and coverage-guided with atheris when installed),
SIGKILL during story saves, simulated power cuts replayed from the product's recorded system calls
(`power_loss`), bad database/package/calibration files, lost tracking, and the UI monkey.
"""
