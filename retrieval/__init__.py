"""StoryBeam's motion side, in layers (each imports only those listed before it):

* :mod:`retrieval.motion` — skeletons, motions, kinematics, body map, file formats;
* :mod:`retrieval.features` — per-frame relational features and pose vectors;
* :mod:`retrieval.codes` — PCA + 2-bit quantiser, distance tables;
* :mod:`retrieval.dtw` — DTW kernels, run-length DTW, bounds, subsequence DTW;
* :mod:`retrieval.search` — the exact fast searches and their brute-force references;
* :mod:`retrieval.library` — clips, datasets, the motion index (the product's search path);
* :mod:`retrieval.animation` — retargeting, foot locking, path following, transitions.

The research's experiment (matchers, baselines, the k-fold evaluation) lives in the lab,
:mod:`lab.experiment`, apart from the product.

:mod:`retrieval.errors` (the :class:`~retrieval.errors.StoryBeamError` hierarchy) is
shared by all. No UI, rendering, OpenCV, tqdm or benchmark code is imported here
(``tests/test_layering.py``).
"""
