"""The act index's library-side augmentation (:class:`retrieval.library.act_search.Augment`):
derived windows (mirrored, tempo-changed, a jump's hop cycle tiled) exist with their
source's label and name, leaving a trial out leaves every window derived from it out (the
answer is the one a library without that trial gives), and a saved index built with
another augmentation is refused."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from retrieval.errors import IndexFormatError
from retrieval.features import get_feature_set
from retrieval.library import ActSearch, clip_from_motion
from retrieval.library.act_search import (AUGMENT, Augment, augmented_clips, hop_cycle, mirror_permutation,
                                          time_scale)
from tests.support.synthetic_motion import make_motion, make_skeleton

FPS = 30.0
NAMES = get_feature_set("frontal").names
HIPS, ANKLES = NAMES.index("hips_height"), [NAMES.index("lankle_height"), NAMES.index("rankle_height")]


def _jump_profile(n: int) -> np.ndarray:
    """Hips height (feature units) of a single jump: standing 2.3, a crouch to 1.9 at
    frame 40, a flight to 2.9 at frame 52, landing dip to 2.0 at frame 62, standing."""
    t = np.arange(n, dtype=float)
    h = np.full(n, 2.3)
    h -= 0.4 * np.exp(-0.5 * ((t - 40) / 4) ** 2)
    h += 0.6 * np.exp(-0.5 * ((t - 52) / 3) ** 2)
    h -= 0.3 * np.exp(-0.5 * ((t - 62) / 3) ** 2)
    return h


def _clips():
    sk = make_skeleton()
    out = []
    for k, (label, kw) in enumerate([("walk", dict(arm_swing=15.0, knee_bend=10.0)),
                                     ("dance", dict(arm_swing=80.0, knee_bend=60.0, bounce=0.08)),
                                     ("jump", dict(arm_swing=40.0, knee_bend=30.0)),
                                     ("jump", dict(arm_swing=50.0, knee_bend=40.0, phase=0.3))]):
        m = make_motion(sk, frames=150, period=0.8 + 0.1 * k, **kw)
        c = clip_from_motion(m, f"t{k}", label, FPS, "frontal", source=f"/lib/t{k}.bvh")
        c.subject = f"s{k}"
        if label == "jump":
            f = c.features.copy()
            f[:, HIPS] = _jump_profile(len(f)) + 0.05 * k
            f[:, ANKLES] = 0.1 + 1.5 * np.maximum(f[:, [HIPS]] - 2.35 - 0.05 * k, 0.0)  # both feet leave the floor
            c = replace(c, features=f)
        out.append(c)
    return out


def test_hop_cycle_runs_from_the_crouch_to_the_landing():
    h = _jump_profile(150)
    a, b = hop_cycle(h, FPS)
    assert 36 <= a <= 44 and 58 <= b <= 66  # the crouch minimum, the landing minimum
    la, lb = hop_cycle(h, FPS, dip=0.0)  # a light hop: where the hips cross their median
    assert a < la < 52 < lb < b
    assert hop_cycle(np.full(150, 2.3), FPS) is None  # no flight, no hop
    assert hop_cycle(h[:3], FPS) is None


def test_only_two_footed_jumps_are_tiled():
    clips = _clips()
    one_foot = clips[2].features.copy()
    one_foot[:, ANKLES[1]] = 0.1  # the right foot stays down: a hop on one foot
    clips[2] = replace(clips[2], features=one_foot)
    derived = augmented_clips(clips, Augment(hops=True), "frontal", 3.5)
    assert [t for _, t, _, _ in derived] == ["t3"]


def test_derived_windows_carry_their_source_label_and_name():
    clips = _clips()
    aug = Augment(mirror=True, tempos=(0.8, 1.25), hops=True)
    derived = augmented_clips(clips, aug, "frontal", 3.5)
    # per clip: its mirror, two tempos of it and of its mirror; per jump one hop window
    assert len(derived) == 4 * (1 + 2 * 2) + 2
    by_trial = {c.trial: c for c in clips}
    perm = mirror_permutation("frontal")
    for clip, trial, start, speed in derived:
        src = by_trial[trial]
        assert clip.trial == trial and clip.label == src.label and clip.subject == src.subject
    mirrored = [d for d in derived if d[3] == 1.0 and len(d[0].features) == len(by_trial[d[1]].features)]
    assert all(np.array_equal(c.features, by_trial[t].features[:, perm]) for c, t, _, _ in mirrored)
    fast = [c for c, t, _, s in derived if s == 1.25]
    assert all(len(c.features) == round(150 / 1.25) for c in fast)
    np.testing.assert_allclose(fast[0].features, time_scale(clips[0].features, 1 / 1.25), rtol=1e-6)
    hops = [(c, t, a) for c, t, a, _ in derived if len(c.features) == round(3.5 * FPS)]
    assert sorted(t for _, t, _ in hops) == ["t2", "t3"] and all(c.label == "jump" for c, _, _ in hops)
    for c, t, a in hops:  # the cycle repeats, end to end
        a, b = hop_cycle(by_trial[t].features[:, HIPS], FPS)
        n = b - a
        np.testing.assert_array_equal(c.features[:n], by_trial[t].features[a:b])
        np.testing.assert_array_equal(c.features[n:2 * n], by_trial[t].features[a:b])


def test_the_index_holds_the_derived_windows_under_their_source_trial():
    clips = _clips()
    plain = ActSearch.from_clips(clips, dims=4, augment=Augment())
    aug = ActSearch.from_clips(clips, dims=4, augment=Augment(mirror=True, hops=True))
    assert plain.augment == "none" and aug.augment == "mirror+hops"
    assert aug.clip_names == plain.clip_names and len(aug) == len(plain) == 4  # no new clips, more windows
    for name in plain.clip_names:
        extra = 1 if name in ("t2", "t3") else 0
        assert aug.names.count(name) == 2 * plain.names.count(name) + extra
    assert aug.short is not None and aug.short.names.count("t2") == 2 * plain.short.names.count("t2") + 1
    labels = {n: lab for n, lab in zip(aug.names, aug.index.labels)}
    assert labels == {c.trial: c.label for c in clips}


@pytest.mark.parametrize("left_out", [["t2"], ["t2", "t3"]])
def test_leaving_a_trial_out_leaves_its_derived_windows_out(left_out):
    """A query that *is* a derived window of t2 (its tiled hop) finds t2 at distance 0;
    with t2 left out (the guard's trial-left-out and subject-left-out protocols name
    trials) the answer is what an augmented library built without it answers."""
    clips = _clips()
    aug = Augment(mirror=True, tempos=(1.25,), hops=True)
    search = ActSearch.from_clips(clips, dims=4, shortlist=10_000, augment=aug)
    hop = next(c for c, t, _, _ in augmented_clips(clips, aug, "frontal", 3.5) if t == "t2" and len(c.features) == 105)
    assert search.search_features(hop.features, k=1)[0].trial == "t2"
    assert search.search_features(hop.features, k=1)[0].distance < 1e-6
    hits = search.search_features(hop.features, k=4, exclude=left_out)
    assert not {h.trial for h in hits} & set(left_out) and len(hits) == 4 - len(left_out)
    without = ActSearch.from_clips([c for c in clips if c.trial not in left_out], dims=4, shortlist=10_000,
                                   augment=aug)
    expected = without.search_features(hop.features, k=4)
    assert [(h.trial, h.label) for h in hits] == [(h.trial, h.label) for h in expected]
    np.testing.assert_allclose([h.distance for h in hits], [h.distance for h in expected], rtol=1e-5)


def test_a_saved_index_is_refused_under_another_augmentation(tmp_path):
    clips = _clips()
    folder = ActSearch.from_clips(clips, dims=4, augment=Augment(hops=True)).save(tmp_path / "act")
    with pytest.raises(IndexFormatError, match="augmentation 'hops'"):
        ActSearch.load(folder)  # the product's augmentation is another one
    again = ActSearch.load(folder, Augment(hops=True))
    assert again.augment == "hops" and again.short is not None and again.short.augment == "hops"
    plain = ActSearch.from_clips(clips, dims=4).save(tmp_path / "plain")
    assert ActSearch.load(plain).augment == AUGMENT.key()
    with pytest.raises(IndexFormatError, match="rebuild"):
        ActSearch.load(plain, Augment(mirror=True))


def test_the_product_index_is_mirrored_with_light_hops():
    """The default act index (what `storybeam search --video` and the app build) holds every
    clip mirrored, so a take done with the other leg finds its trial, and tiles the
    two-footed jumps' light hops; undoing :data:`AUGMENT` fails this."""
    clips = _clips()
    search = ActSearch.from_clips(clips, dims=4, shortlist=10_000)
    assert search.augment == AUGMENT.key() == "mirror+hops@0.3"
    walk = clips[0].features[:105]
    mirrored = walk[:, mirror_permutation("frontal")]
    assert not np.allclose(mirrored, walk)
    hit = search.search_features(mirrored, k=1)[0]
    assert hit.trial == "t0" and hit.distance < 1e-6
    plain = ActSearch.from_clips(clips, dims=4, shortlist=10_000, augment=Augment())
    assert plain.search_features(mirrored, k=1)[0].distance > 1e-3
    assert len(search.names) > 2 * len(plain.names)  # mirrored windows and the tiled hops
