"""A library that groups itself: kinetic energy per body part against a plain loop, the
clip descriptor, the silhouette / purity / adjusted Rand index against brute-force
references, the grouping on separable data (K chosen by the silhouette, names, pictures)
and `storybeam cluster` on a small folder."""
from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from retrieval.errors import StoryBeamError
from retrieval.features import BODY_PARTS, kinetic_energy, kinetic_energy_from_positions, leg_length
from retrieval.library import (
    adjusted_rand_index,
    clip_descriptor,
    descriptor_matrix,
    group,
    group_folder,
    purity,
    silhouette,
)
from retrieval.motion import canonical_joint_map, positions
from tests.support.synthetic_motion import make_motion, make_skeleton, write_bvh


# ------------------------------------------------------------------ kinetic energy
def test_kinetic_energy_equals_a_plain_loop():
    sk = make_skeleton()
    motion = make_motion(sk, frames=25, fps=30.0, arm_swing=50, bounce=0.1)
    jm = canonical_joint_map(sk)
    pos = positions(motion)
    size = leg_length(sk, jm)
    got = kinetic_energy(motion)
    assert got.shape == (25, len(BODY_PARTS))
    for t in (0, 1, 12, 24):
        lo, hi = max(t - 1, 0), min(t + 1, 24)
        for p, joints in enumerate(BODY_PARTS.values()):
            e = 0.0
            for j in joints:
                v = (pos[hi, jm[j]] - pos[lo, jm[j]]) / ((hi - lo) / 30.0) / size
                e += 0.5 * float(v @ v)
            assert got[t, p] == pytest.approx(e / len(joints), rel=1e-9)


def test_kinetic_energy_ignores_heading_and_place_and_is_zero_for_a_still_body():
    sk = make_skeleton()
    jm = canonical_joint_map(sk)
    pos = positions(make_motion(sk, frames=30, arm_swing=40))
    c, s = np.cos(1.2), np.sin(1.2)
    turned = pos @ np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]]).T + np.array([3.0, 0.2, -1.0])
    np.testing.assert_allclose(kinetic_energy_from_positions(turned, jm, 0.9, 30.0),
                               kinetic_energy_from_positions(pos, jm, 0.9, 30.0), rtol=1e-9, atol=1e-12)
    still = np.repeat(positions(make_motion(sk, frames=1)), 10, axis=0)
    assert np.all(kinetic_energy_from_positions(still, jm, 1.0, 30.0) == 0)
    assert kinetic_energy_from_positions(still[:1], jm, 1.0, 30.0).shape == (1, 5)
    with pytest.raises(StoryBeamError, match="positive"):
        kinetic_energy_from_positions(still, jm, 1.0, 0.0)
    with pytest.raises(StoryBeamError, match="needs joints"):
        kinetic_energy_from_positions(still, {"hips": 0}, 1.0, 30.0)


# ------------------------------------------------------------------ descriptor
def test_clip_descriptor_blocks():
    rng = np.random.default_rng(1)
    energy = rng.random((40, 5))
    codes = rng.integers(0, 4 ** 3, 33)
    kinetic, hist = clip_descriptor(energy, codes, 3)
    assert kinetic.shape == (20,) and hist.shape == (12,)
    assert kinetic[10:15].sum() == pytest.approx(1.0) and kinetic[15:20].sum() == pytest.approx(1.0)
    for d in range(3):
        for v in range(4):
            expect = sum(1 for c in codes if (int(c) >> (2 * d)) & 3 == v) / len(codes)
            assert hist[d * 4 + v] == pytest.approx(expect)
    with pytest.raises(StoryBeamError, match="kinetic energy must be"):
        clip_descriptor(energy[:, :3], codes, 3)
    with pytest.raises(StoryBeamError, match="codes must be"):
        clip_descriptor(energy, codes[:0], 3)


def test_descriptor_matrix_standardises_and_weighs_blocks_equally():
    rng = np.random.default_rng(2)
    blocks = [(rng.normal(size=20) * 50, np.r_[rng.random(11), 0.3]) for _ in range(15)]
    x = descriptor_matrix(blocks)
    assert x.shape == (15, 32)
    np.testing.assert_allclose(x.mean(axis=0), 0, atol=1e-12)
    np.testing.assert_allclose(x[:, :20].std(axis=0), 1 / np.sqrt(20))
    np.testing.assert_allclose(x[:, 20:31].std(axis=0), 1 / np.sqrt(12))
    assert np.all(x[:, 31] == 0)  # a constant column carries nothing


# ------------------------------------------------------------------ scores
def _silhouette_reference(x, labels):
    n = len(x)
    out = []
    for i in range(n):
        same = [np.linalg.norm(x[i] - x[j]) for j in range(n) if j != i and labels[j] == labels[i]]
        if not same:
            out.append(0.0)
            continue
        a = np.mean(same)
        b = min(np.mean([np.linalg.norm(x[i] - x[j]) for j in range(n) if labels[j] == c])
                for c in set(labels) if c != labels[i])
        out.append((b - a) / max(a, b))
    return float(np.mean(out))


def _ari_reference(u, v):
    """Pair counting (Steinley 2004): a = pairs together in both, d = apart in both."""
    a = b = c = d = 0
    for i, j in itertools.combinations(range(len(u)), 2):
        su, sv = u[i] == u[j], v[i] == v[j]
        a += su and sv
        b += su and not sv
        c += sv and not su
        d += not su and not sv
    den = (a + b) * (b + d) + (a + c) * (c + d)
    return 1.0 if den == 0 else 2 * (a * d - b * c) / den


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_silhouette_purity_and_ari_equal_their_references(seed):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(30, 4))
    clusters = rng.integers(0, 4, 30)
    clusters[:2] = [7, 8]  # two singletons
    labels = [str(v) for v in rng.choice(["walk", "run", "jump"], 30)]
    assert silhouette(x, clusters) == pytest.approx(_silhouette_reference(x, list(clusters)), abs=1e-12)
    assert adjusted_rand_index(clusters, labels) == pytest.approx(_ari_reference(list(clusters), labels), abs=1e-12)
    by = {}
    for c, lab in zip(clusters, labels):
        by.setdefault(c, []).append(lab)
    assert purity(clusters, labels) == pytest.approx(sum(max(v.count(lab) for lab in v) for v in by.values()) / 30)


def test_scores_of_perfect_and_relabelled_partitions():
    labels = ["a"] * 5 + ["b"] * 4 + ["c"] * 3
    renamed = [{"a": 2, "b": 0, "c": 1}[lab] for lab in labels]
    assert adjusted_rand_index(renamed, labels) == 1.0 and purity(renamed, labels) == 1.0
    assert purity([0] * 12, labels) == pytest.approx(5 / 12)
    assert adjusted_rand_index([0] * 12, labels) == pytest.approx(0.0)
    with pytest.raises(StoryBeamError):
        silhouette(np.zeros((4, 2)), [0, 0, 0, 0])
    with pytest.raises(StoryBeamError):
        purity([0, 1], ["a"])


# ------------------------------------------------------------------ grouping
def _blobs(rng, sizes=(9, 7, 5), spread=0.2):
    centres = np.array([[0, 0, 0], [6, 0, 0], [0, 6, 0]], dtype=float)
    x = np.concatenate([c + rng.normal(scale=spread, size=(n, 3)) for c, n in zip(centres, sizes)])
    truth = np.repeat(np.arange(len(sizes)), sizes)
    return x, truth


def test_group_finds_separable_groups_and_names_them():
    rng = np.random.default_rng(4)
    x, truth = _blobs(rng)
    trials = [f"t{i}" for i in range(len(x))]
    labels = [["walk", "run", "jump"][t] for t in truth]
    labels[1] = "run"  # a stray label: the group stays "walk" (most common)
    labels[9:16] = [""] * 7  # the second blob was imported without labels
    g = group(x, trials, labels, k_min=2)
    assert g.k == 3 and max(g.scores, key=g.scores.get) == 3 and min(g.scores) == 2
    assert adjusted_rand_index(g.clusters, truth) == 1.0
    assert [len(grp.members) for grp in g.groups] == [9, 7, 5]  # largest first
    assert [grp.name for grp in g.groups] == ["walk", None, "jump"]
    for grp in g.groups:  # the representative is the medoid
        sums = [sum(np.linalg.norm(x[i] - x[j]) for j in grp.members) for i in grp.members]
        assert grp.representative == trials[grp.members[int(np.argmin(sums))]]
        assert all(g.clusters[i] == grp.number for i in grp.members)
    fixed = group(x, trials, labels, k=2)
    assert fixed.k == 2 and fixed.scores == {} and len(fixed.groups) == 2
    at_least = group(x, trials, labels, k_min=4, k_max=6)  # the range's lower end binds
    assert at_least.k >= 4 and sorted(at_least.scores) == [4, 5, 6]


def test_group_refuses_bad_input():
    x = np.zeros((5, 2))
    with pytest.raises(StoryBeamError, match="at least 3"):
        group(x[:2], ["a", "b"])
    with pytest.raises(StoryBeamError, match="differ in length"):
        group(x, ["a"] * 4)
    with pytest.raises(StoryBeamError, match="K must lie"):
        group(x, list("abcde"), k=9)
    with pytest.raises(StoryBeamError, match="K range"):
        group(x, list("abcde"), k_min=5, k_max=3)


# ------------------------------------------------------------------ folder and command
@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """Two kinds of clip, 4 each: small slow swings and big fast ones."""
    sk = make_skeleton()
    root = tmp_path_factory.mktemp("group") / "lib"
    root.mkdir()
    rows = ["trial,label,file,skeleton"]
    for i in range(8):
        big = i >= 4
        m = make_motion(sk, frames=40, arm_swing=70 + 3 * i if big else 8 + i, knee_bend=45 if big else 5,
                        period=0.5 if big else 2.0, bounce=0.12 if big else 0.0, phase=0.4 * i)
        write_bvh(m, root / f"m{i}.bvh")
        rows.append(f"m{i},{'run' if big else 'idle'},m{i}.bvh,")
    (root / "labels.csv").write_text("\n".join(rows) + "\n")
    return root


def test_group_folder_separates_the_two_kinds(folder):
    res = group_folder(folder, fps=30.0, dims=3, k=2)
    assert res.trials == tuple(f"m{i}" for i in range(8))
    assert purity(res.grouping.clusters, res.labels) == 1.0
    assert sorted(grp.name for grp in res.grouping.groups) == ["idle", "run"]
    assert res.descriptors.shape[0] == 8


def test_cluster_command_writes_k_purity_and_ari(folder, tmp_path, capsys):
    from app.cli import main

    out = tmp_path / "c.json"
    assert main(["cluster", "--data", str(folder), "--json", str(out), "--dims", "3", "--k-min", "2",
                 "--k-max", "4", "--quiet"]) == 0
    r = json.loads(out.read_text())
    assert {"clusters", "purity", "ari", "criterion", "groups", "silhouette"} <= set(r)
    assert 2 <= r["clusters"] <= 4 and sum(g["size"] for g in r["groups"]) == 8
    expect = group_folder(folder, 30.0, 3, None, 4, k_min=2)
    assert r["clusters"] == expect.grouping.k
    assert r["purity"] == purity(expect.grouping.clusters, expect.labels)
    assert r["ari"] == adjusted_rand_index(expect.grouping.clusters, expect.labels)
    assert r["at_label_count"]["clusters"] == 2 and r["at_label_count"]["purity"] == 1.0
    assert "purity" in capsys.readouterr().out


@pytest.mark.parametrize("extra, message", [
    (["--k-max", "1"], "2 <= k-min"), (["--k-min", "5", "--k-max", "3"], "2 <= k-min"), (["--dims", "0"], "--dims"),
    (["--fps", "0"], "--fps"),
])
def test_cluster_command_refuses_bad_options_plainly(folder, capsys, extra, message):
    from app.cli import main

    assert main(["cluster", "--data", str(folder), "--quiet", *extra]) == 1
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
