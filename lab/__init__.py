"""StoryBeam's lab: what measures and attacks the product, kept apart from it.

* :mod:`lab.experiment` -- the research's experiment: matchers, baselines and the k-fold
  1-NN evaluation (``storybeam eval``);
* :mod:`lab.bench` -- the benchmarks (``storybeam bench TARGET``), each printing a table
  and writing JSON;
* :mod:`lab.stress` -- the robustness harnesses (``storybeam stress``): fuzzed files,
  kills and simulated power cuts during saves, lost tracking, the UI monkey.

The lab may use anything of ``retrieval/``, ``ar/`` and ``app/``; nothing there imports
the lab except the command modules in :mod:`app.commands` (``tests/test_layering.py``).
"""
