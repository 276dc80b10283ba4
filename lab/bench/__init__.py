"""Benchmarks, run as ``storybeam bench <target>``: each module measures one part of the
product and returns a JSON-ready dict plus a printable table. Nothing in the library
(``retrieval/``, ``ar/``) or the app's own layers imports this package."""
