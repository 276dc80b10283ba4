"""Tests of the lab (lab/): the research experiment, the benchmarks' pieces and the rival search."""
