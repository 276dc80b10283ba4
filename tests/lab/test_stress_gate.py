"""`storybeam stress gate` (lab/stress/gate.py): scripted children get nothing through the
grown-up check and every lock holds; a weakened gate (no locks, ten possible answers)
lets them through, so the harness can see a pass; the grown-up model reads the real words."""
from __future__ import annotations

import json
import math
import random
import subprocess
import sys
from pathlib import Path

import pytest

from app.story import storage
from lab.stress import gate
from lab.stress.gate import STRATEGIES, ChildTally, grownup_seconds, run_child, tap_seconds

REPO = Path(__file__).resolve().parents[2]


def _day_attempts(day_s: float) -> int:
    """Answers a perfectly persistent child gets checked in ``day_s``, written out apart
    from the gate: 30 s, 1, 2, 5 min, then 15 min between them (typing time ignored)."""
    t, n = 0.0, 0
    locks = [30, 60, 120, 300] + [900] * 1000
    while t <= day_s:
        n += 1
        t += locks[n - 1]
    return n


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_no_scripted_child_passes_and_no_lock_is_cut_short(tmp_path, strategy):
    tally = ChildTally()
    for k in range(3):
        run_child(strategy, tmp_path / f"{k}.db", random.Random(k), tally, day_s=3 * 3600.0)
    assert tally.children == 3 and tally.passes == 0 and tally.lock_violations == 0
    assert tally.longest_lock_s == 900
    # persistent: about as many checked answers as the locks allow, never more
    assert 0.8 * _day_attempts(3 * 3600.0) <= min(tally.attempts_per_day)
    assert max(tally.attempts_per_day) <= _day_attempts(3 * 3600.0)
    if strategy == "restarts":
        assert tally.restarts == tally.attempts
    if strategy == "clock_changes":
        assert tally.reboots == tally.attempts


def test_a_weak_gate_is_caught(tmp_path, monkeypatch):
    """The control: no locks and ten possible answers. The same children pass at once."""
    monkeypatch.setattr(storage.teacher, "GROWNUP_LOCKS_S", (0.0,))
    for module in (storage.teacher, gate):  # the questions, and the children's six-digit guesses
        monkeypatch.setattr(module, "GROWNUP_MIN", 100_000)
        monkeypatch.setattr(module, "GROWNUP_MAX", 100_009)
    tally = ChildTally()
    for k in range(3):
        for strategy in ("restarts", "seen_answer"):
            run_child(strategy, tmp_path / f"{strategy}{k}.db", random.Random(k), tally, day_s=600.0)
    assert tally.passes >= 3


def test_the_grown_up_model_on_the_real_words_and_pad(tmp_path):
    assert tap_seconds("1") == pytest.approx(0.20 + 0.15 * math.log2(2 * 113.33 / 103.33 + 1), rel=1e-3)
    assert tap_seconds("11") < tap_seconds("19")  # a far key takes longer (Fitts)
    for lang in ("en", "ja"):
        times = [grownup_seconds(tmp_path / f"{lang}{k}.db", random.Random(k), lang)[0] for k in range(30)]
        assert 5 < sorted(times)[15] < 30


@pytest.mark.slow  # the command end to end (a few seconds)
def test_stress_gate_command_writes_its_json(tmp_path):
    out = tmp_path / "gate.json"
    proc = subprocess.run([sys.executable, "-m", "app.cli", "stress", "gate", "--children", "1", "--grownups", "5",
                           "--json", str(out), "--work-dir", str(tmp_path / "work")],
                          cwd=REPO, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    data = json.loads(out.read_text())
    assert data["child_passes"] == 0 and data["lock_violations"] == 0 and data["child_days"] == len(STRATEGIES)
    assert data["child_attempts"] > 25 * len(STRATEGIES) and data["grownup_seconds_median"] < 30
    assert set(data["strategies"]) == set(STRATEGIES)
