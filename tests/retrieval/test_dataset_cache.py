"""The clip cache of :mod:`retrieval.library.dataset` when two writers fill one entry at
once (the app's background library load beside a command, parallel test workers): the
entry ends as one writer's whole file, never a mix, and no temporary file is left.

Two processes are simulated in one: the first writer's ``np.savez`` writes half of its
file, then the second writer loads the same row through the cache from start to end,
then the first writes the rest. Its file differs from the second's (an extra array), so
a mix of the two is not a valid archive."""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from retrieval.library import dataset

REPO = Path(__file__).resolve().parents[2]


def test_two_writers_of_one_cache_entry_leave_one_whole_file(tmp_path, monkeypatch):
    row = dataset.read_labels(REPO / "assets" / "motions")[0]
    real_savez = np.savez
    calls = []

    def interleaved_savez(file, **arrays):
        calls.append(file)
        if len(calls) > 1:  # the second writer runs undisturbed
            return real_savez(file, **arrays)
        buf = io.BytesIO()
        real_savez(buf, marker=np.arange(5), **arrays)
        data = buf.getvalue()
        fh = open(file, "wb") if isinstance(file, (str, Path)) else file
        try:
            fh.write(data[: len(data) // 2])
            fh.flush()
            dataset.load_row(row, 30.0, "frontal", tmp_path)  # the other writer, start to end
            fh.write(data[len(data) // 2:])
            fh.flush()
        finally:
            if fh is not file:
                fh.close()

    monkeypatch.setattr(np, "savez", interleaved_savez)
    first = dataset.load_row(row, 30.0, "frontal", tmp_path)
    monkeypatch.setattr(np, "savez", real_savez)

    assert len(calls) == 2
    entries = list(tmp_path.iterdir())
    assert [p.suffix for p in entries] == [".npz"], entries  # one entry, no temporary left behind
    with np.load(entries[0]) as z:  # a whole archive: the first writer's, renamed last
        assert set(z.files) == {"features", "pose", "fps", "marker"}
        np.testing.assert_array_equal(z["features"], first.features)
    again = dataset.load_row(row, 30.0, "frontal", tmp_path)  # read back from the cache
    np.testing.assert_array_equal(again.features, first.features)
