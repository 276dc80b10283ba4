"""The layering the project promises, enforced.

Two kinds of check:

* **at run time** — every module of a package is imported in a fresh interpreter and the
  loaded modules are compared with what the package must never pull in (so an indirect
  import is caught too): ``retrieval/`` runs on Android without pyrender and in batch jobs
  without a display; ``ar/`` runs without Kivy; ``app.story`` without any UI or GL stack;
* **statically** — every ``.py`` under ``retrieval/``, ``ar/`` and ``app/`` is parsed
  (:mod:`tests.support.imports`, shared with ``scripts/draw_architecture.py``) and its
  imports are checked against the rules written as data below: which layer may import
  which, which third-party modules a layer may not touch, no import cycle, no
  function-level import without an ``optional:``/``deferred:`` comment, no other module's
  ``_private`` names, curated ``__init__.py`` files.

Each check is its own test, reports every offender with ``file:line`` and the import, and
has a self-test on a synthetic package (``test_checkers_catch_*``) showing it can fail.
The diagram in docs/design/architecture.md is generated from the same scan; a test keeps it true.
"""
from __future__ import annotations

import ast
import importlib.util
import json
import subprocess
import sys
import textwrap
from collections.abc import Iterable, Mapping
from pathlib import Path

import pytest

from tests.support.imports import (
    PACKAGES,
    REPO,
    STDLIB,
    UNITS,
    Module,
    bound_names,
    discover,
    find_cycle,
    is_storybeam,
    is_third_party,
    module_graph,
    scan,
    unit_of,
)

# --------------------------------------------------------------------------------------
# The rules, as data
# --------------------------------------------------------------------------------------

ERRORS = "retrieval.errors"

#: retrieval's layers. Each may import the layers listed for it (and itself), nothing else
#: of StoryBeam. Every layer may use retrieval.errors.
RETRIEVAL_ALLOWED: dict[str, tuple[str, ...]] = {
    "retrieval": (),  # the package docstring only
    ERRORS: (),
    # durable file writes (stdlib only): the lowest layer, for ar's calibration files and app's store
    "retrieval.durable": (),
    "retrieval.motion": (ERRORS,),
    "retrieval.features": (ERRORS, "retrieval.motion"),
    "retrieval.codes": (ERRORS,),  # codes work on any feature matrix
    "retrieval.dtw": (ERRORS, "retrieval.codes"),
    "retrieval.search": (ERRORS, "retrieval.codes", "retrieval.dtw"),
    "retrieval.library": (
        ERRORS, "retrieval.motion", "retrieval.features", "retrieval.codes", "retrieval.dtw", "retrieval.search",
    ),
    # animation never uses the search (dtw, search, library, experiment)
    "retrieval.animation": (ERRORS, "retrieval.motion", "retrieval.features", "retrieval.codes"),
}
RETRIEVAL_ALL = tuple(RETRIEVAL_ALLOWED)
#: What the product side of app/ may use of retrieval: it searches only through
#: retrieval.library (MotionIndex), never dtw/search/experiment directly.
RETRIEVAL_PRODUCT = (
    ERRORS, "retrieval.durable", "retrieval.motion", "retrieval.features", "retrieval.codes", "retrieval.library", "retrieval.animation",
)
AR_ALL = ("ar", "ar.body", "ar.scene", "ar.render", "ar.closed_loop")
#: Shared by every part of app/: the checkout's paths, the progress-bar callback.
APP_BASE = ("app.paths", "app.progress")

#: unit -> the other units it may import (a whitelist; see tests.support.imports.UNITS).
ALLOWED: dict[str, tuple[str, ...]] = {
    **RETRIEVAL_ALLOWED,
    # ar core (errors, geometry, boards, pose, filtering, calibration, synthetic): no rendering
    "ar": (ERRORS, "retrieval.durable"),
    # body pose from camera frames (BlazePose through a TFLite interpreter): on the core, and
    # retrieval.motion for the one table of BlazePose's landmarks (LANDMARK_NAMES), which the
    # retrieval side turns into joints and may not import ar for
    "ar.body": ("ar", ERRORS, "retrieval.durable", "retrieval.motion"),
    # the renderer-agnostic scene (numpy meshes, characters, views): no GL, no trimesh
    "ar.scene": ("ar", ERRORS, "retrieval.motion", "retrieval.animation"),
    # the pyrender/trimesh renderer, on top of the core and the scene
    "ar.render": ("ar", "ar.scene", ERRORS, "retrieval.motion", "retrieval.animation"),
    # the closed loop checks landings by rendering through ar.render
    "ar.closed_loop": ("ar", "ar.scene", "ar.render", ERRORS),
    "app": (),
    "app.paths": (),
    "app.progress": (),
    "app.story": (*APP_BASE, *RETRIEVAL_PRODUCT),
    "app.services": (*APP_BASE, "app.story", "ar", "ar.body", *RETRIEVAL_PRODUCT),
    "app.player": (*APP_BASE, "app.story", *AR_ALL, *RETRIEVAL_PRODUCT),
    # app.ui draws ar.scene descriptions with Kivy GL (app.ui.gl); never ar.render (pyrender)
    "app.ui": (*APP_BASE, "app.story", "app.services", "app.player", "ar.scene", *RETRIEVAL_PRODUCT,
               "ar",  # ar core: the Kivy camera is an ar.camera_sources.CameraSource (issue 13)
               "ar.body"),  # "Act it out": the body skeleton drawn over the camera preview (issue 18)
    # the lab (lab/): the research experiment on retrieval only; the harnesses on anything of
    # the product, never the commands (bench never the UI)
    "lab": (),
    "lab.experiment": (*RETRIEVAL_ALL,),
    "lab.bench": (*APP_BASE, *RETRIEVAL_ALL, *AR_ALL, "app.story", "app.services", "app.player", "lab.experiment"),
    "lab.stress": (*APP_BASE, *RETRIEVAL_ALL, *AR_ALL, "app.story", "app.services", "app.player", "app.ui"),
    "app.commands": tuple(u for u in UNITS if u not in ("app", "app.cli", "app.commands")),
    "app.cli": ("app.commands", ERRORS),
}

_NO_UI = ("kivy", "pyrender", "OpenGL", "trimesh", "cv2")
#: unit -> third-party top-level modules it may never import (anywhere in the file).
FORBIDDEN_THIRD_PARTY: dict[str, tuple[str, ...]] = {
    **{unit: (*_NO_UI, "tqdm", "dtaidistance", "PIL", "imageio", "imageio_ffmpeg") for unit in RETRIEVAL_ALL},
    "ar": ("kivy", "pyrender", "OpenGL", "trimesh", "tqdm", "dtaidistance"),
    "ar.body": ("kivy", "pyrender", "OpenGL", "trimesh", "tqdm", "dtaidistance"),
    "ar.scene": ("kivy", "pyrender", "OpenGL", "trimesh", "tqdm", "dtaidistance"),
    "ar.render": ("kivy",),
    "ar.closed_loop": ("kivy",),
    "lab.experiment": (*_NO_UI, "tqdm", "dtaidistance", "PIL", "imageio", "imageio_ffmpeg"),
    "app.paths": ("kivy", "pyrender", "OpenGL", "trimesh", "cv2"),
    "app.progress": ("kivy", "pyrender", "OpenGL", "trimesh", "cv2"),
    "app.story": _NO_UI,
    "app.services": ("kivy", "pyrender", "OpenGL", "trimesh"),
    "app.player": ("kivy",),
}

#: third-party module -> the only modules that may import it.
ONLY_IMPORTED_BY: dict[str, tuple[str, ...]] = {
    "numba": ("retrieval.dtw.jit",),  # the one place numba is imported (and its cache set)
    # the TFLite interpreters (desktop / tablet): only the pose models' loader
    "ai_edge_litert": ("ar.body.models",),
    "tflite_runtime": ("ar.body.models",),
}

#: Harness packages, and the units that may import them.
HARNESSES = ("lab", "lab.experiment", "lab.bench", "lab.stress")
HARNESS_USERS = ("app.commands", "app.cli")

#: Imports of another retrieval layer go through its package (`from retrieval.dtw import
#: lower_bound`), except these modules, imported directly: (importing unit, module, why).
SUBMODULE_IMPORTS_ALLOWED: tuple[tuple[str, str, str], ...] = (
    ("*", "retrieval.dtw.jit", "the numba handle, for modules that compile kernels of their own"),
    ("retrieval.search", "retrieval.dtw.runlength", "compiled kernels, present only with numba"),
    ("retrieval.search", "retrieval.dtw.range_bound", "compiled kernels, present only with numba"),
    # the fast search's DPs, compiled beside their numpy twins in dtw (issue 30, "Kernels beside their twins")
    ("retrieval.search", "retrieval.dtw.block_corner", "compiled kernels, present only with numba"),
    ("retrieval.search", "retrieval.dtw.rowscan", "compiled kernels, present only with numba"),
    ("retrieval.search", "retrieval.dtw.kernels", "compiled kernels (band_limits_nb), present only with numba"),
)

#: Fresh-interpreter checks: name -> (module prefixes imported, prefixes skipped, forbidden).
RUNTIME_FORBIDDEN: dict[str, tuple[tuple[str, ...], tuple[str, ...], tuple[str, ...]]] = {
    "retrieval": (
        ("retrieval",), (),
        ("kivy", "pyrender", "OpenGL", "trimesh", "cv2", "ar", "app", "tqdm", "dtaidistance", "matplotlib"),
    ),
    "ar": (("ar",), (), ("kivy", "app")),
    "ar-core": (("ar",), ("ar.render", "ar.closed_loop"), ("kivy", "app", "pyrender", "OpenGL", "trimesh")),
    "ar.body": (("ar.body",), (), ("kivy", "app", "pyrender", "OpenGL", "trimesh", "ai_edge_litert", "tflite_runtime")),
    "ar.scene": (("ar.scene",), (), ("kivy", "app", "pyrender", "OpenGL", "trimesh")),
    "app.story": (("app.story",), (), ("kivy", "pyrender", "OpenGL", "trimesh", "cv2", "ar")),
    "app.services": (("app.services",), (), ("kivy", "pyrender", "OpenGL", "trimesh")),
    "app.player": (("app.player",), (), ("kivy",)),
}

MARKERS = ("optional", "deferred")


# --------------------------------------------------------------------------------------
# The checkers (pure functions of a scan, so the self-tests can feed them a bad package)
# --------------------------------------------------------------------------------------


def _dedupe(lines: Iterable[str]) -> list[str]:
    return list(dict.fromkeys(lines))


def _rel(path: Path, root: Path) -> str:
    try:
        return str(path.relative_to(root))
    except ValueError:
        return str(path)


def layer_offences(
    modules: Mapping[str, Module], allowed: Mapping[str, Iterable[str]], units: Iterable[str], root: Path = REPO
) -> list[str]:
    """Imports (at any level) of a unit the importer's unit may not import."""
    units = tuple(units)
    out = []
    for module in modules.values():
        source = unit_of(module.name, units)
        for imp in module.imports:
            target = unit_of(imp.target, units)
            if source is None or target is None or target == source:
                continue
            if target not in set(allowed.get(source, ())):
                out.append(
                    f"{imp.where(root)}: {module.name} (layer {source}) imports {imp.target} "
                    f"(layer {target}), which {source} may not import: {imp.statement}"
                )
    return _dedupe(out)


def third_party_offences(
    modules: Mapping[str, Module],
    forbidden: Mapping[str, Iterable[str]],
    only_by: Mapping[str, Iterable[str]],
    units: Iterable[str],
    root: Path = REPO,
) -> list[str]:
    """Imports of a third-party module the importer's unit may not use, or that only
    named modules may import."""
    units = tuple(units)
    out = []
    for module in modules.values():
        unit = unit_of(module.name, units)
        for imp in module.imports:
            if not is_third_party(imp.target, PACKAGES + tuple(u.split(".")[0] for u in units)):
                continue
            if imp.top in set(forbidden.get(unit, ())):
                out.append(f"{imp.where(root)}: {module.name} (layer {unit}) may not import {imp.top}: {imp.statement}")
            if imp.top in only_by and module.name not in set(only_by[imp.top]):
                out.append(
                    f"{imp.where(root)}: {imp.top} is imported only by {', '.join(only_by[imp.top])}, "
                    f"not {module.name}: {imp.statement}"
                )
    return _dedupe(out)


def harness_offences(modules: Mapping[str, Module], root: Path = REPO) -> list[str]:
    """Imports of the lab (lab.*) from outside the commands (the lab may use its own
    modules)."""
    out = []
    for module in modules.values():
        source = unit_of(module.name)
        for imp in module.imports:
            target = unit_of(imp.target)
            if target in HARNESSES and source not in HARNESSES and source not in HARNESS_USERS:
                out.append(f"{imp.where(root)}: {module.name} imports the harness {imp.target}: {imp.statement}")
            if target == "app.commands" and source not in ("app.commands", "app.cli"):
                out.append(f"{imp.where(root)}: {module.name} imports the command module {imp.target}")
    return _dedupe(out)


def facade_offences(
    modules: Mapping[str, Module], exceptions: Iterable[tuple[str, str, str]] = SUBMODULE_IMPORTS_ALLOWED,
    root: Path = REPO,
) -> list[str]:
    """Imports of a module inside another retrieval layer instead of through that layer's
    package (its curated ``__init__``); subpackages such as retrieval.motion.formats are
    packages with curated ``__init__`` files of their own and count as the surface."""
    allowed = {(unit, target) for unit, target, _why in exceptions}
    out = []
    for module in modules.values():
        source = unit_of(module.name)
        for imp in module.imports:
            target_unit = unit_of(imp.target)
            if target_unit is None or not target_unit.startswith("retrieval.") or target_unit in (source, imp.target):
                continue
            target = modules.get(imp.target)
            if target is None or target.is_package:
                continue
            if ("*", imp.target) in allowed or (source, imp.target) in allowed:
                continue
            out.append(
                f"{imp.where(root)}: {module.name} imports {imp.target} directly; import it from "
                f"{target_unit} (add the name to its __init__/__all__): {imp.statement}"
            )
    return _dedupe(out)


def cycle_in(modules: Mapping[str, Module]) -> list[str] | None:
    """One cycle of module-level imports, or None."""
    return find_cycle(module_graph(modules))


def function_level_offences(modules: Mapping[str, Module], root: Path = REPO) -> list[str]:
    """Imports inside a def/class body of StoryBeam or third-party modules without an
    ``optional:``/``deferred:`` comment on the line or the line above."""
    out = []
    for module in modules.values():
        for imp in module.imports:
            if not imp.function_level or imp.marker in MARKERS or imp.top in STDLIB:
                continue
            out.append(f"{imp.where(root)}: {imp.statement}")
    return _dedupe(out)


def private_offences(modules: Mapping[str, Module], root: Path = REPO) -> list[str]:
    """``from m import _name`` (a private name or private module of another module)."""
    out = []
    for module in modules.values():
        for imp in module.imports:
            names = [imp.name] if imp.name else []
            names += imp.target.split(".")
            private = [n for n in names if n.startswith("_") and not (n.startswith("__") and n.endswith("__"))]
            if private:
                out.append(f"{imp.where(root)}: {module.name} imports {', '.join(private)} from {imp.target}")
    return _dedupe(out)


def _literal_all(tree: ast.Module) -> list[str] | None:
    for node in tree.body:
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(node, ast.AnnAssign) else []
        if any(isinstance(t, ast.Name) and t.id == "__all__" for t in targets):
            try:
                return list(ast.literal_eval(node.value))
            except ValueError:
                return []
    return None


def package_offences(
    modules: Mapping[str, Module], root: Path = REPO, packages: Iterable[str] = PACKAGES,
    curated: Iterable[str] = ("retrieval.",),
) -> list[str]:
    """Every folder of .py files is a package whose ``__init__`` has a docstring; the
    packages under the ``curated`` prefixes define ``__all__``, every name in it exists,
    appears once, and every public name the ``__init__`` imports is in it."""
    out = []
    for package in packages:
        for folder in sorted({p.parent for p in (root / package).rglob("*.py") if "__pycache__" not in p.parts}):
            if not (folder / "__init__.py").is_file():
                out.append(f"{_rel(folder, root)}/: a folder of modules without an __init__.py")
    for module in modules.values():
        if not module.is_package:
            continue
        where = _rel(module.path, root)
        if not module.docstring:
            out.append(f"{where}:1: package {module.name} has no docstring")
        if not any(module.name.startswith(prefix) for prefix in curated):
            continue
        names = _literal_all(module.tree)
        if names is None:
            out.append(f"{where}: package {module.name} does not define __all__")
            continue
        bound = bound_names(module.tree)
        for name in names:
            if name not in bound:
                out.append(f"{where}: __all__ of {module.name} lists {name!r}, which it does not define")
        for name in sorted({n for n in names if names.count(n) > 1}):
            out.append(f"{where}: __all__ of {module.name} lists {name!r} twice")
        imported = {
            imp.bound for imp in module.imports
            if imp.bound and not imp.function_level and imp.target != "__future__" and not imp.bound.startswith("_")
        }
        for name in sorted(imported - set(names)):
            out.append(f"{where}: {module.name} imports {name!r} but leaves it out of __all__")
    return _dedupe(out)


def _report(title: str, offences: list[str], hint: str) -> str:
    return f"{len(offences)} {title}:\n  " + "\n  ".join(offences) + f"\n{hint}"


# --------------------------------------------------------------------------------------
# The checks on the real tree
# --------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def modules() -> dict[str, Module]:
    return scan()


def test_every_module_has_a_layer_with_rules(modules):
    orphans = sorted(
        name for name in modules
        if unit_of(name) is None or (unit_of(name) in ("retrieval", "app") and not modules[name].is_package)
    )
    assert not orphans, f"modules outside every unit of tests/support/imports.py UNITS: {orphans}"
    missing = sorted({unit_of(name) for name in modules} - set(ALLOWED))
    assert not missing, f"units with no rule in ALLOWED (tests/test_layering.py): {missing}"
    assert set(ALLOWED) <= set(UNITS), sorted(set(ALLOWED) - set(UNITS))


def test_layers_import_only_the_layers_below(modules):
    offences = layer_offences(modules, ALLOWED, UNITS)
    assert not offences, _report(
        "imports across the layering", offences, "the allowed imports per layer are ALLOWED in tests/test_layering.py"
    )


def test_layers_keep_off_forbidden_third_party_modules(modules):
    offences = third_party_offences(modules, FORBIDDEN_THIRD_PARTY, ONLY_IMPORTED_BY, UNITS)
    assert not offences, _report("forbidden third-party imports", offences, "see FORBIDDEN_THIRD_PARTY")


def test_only_commands_import_the_harnesses(modules):
    offences = harness_offences(modules)
    assert not offences, _report("imports of lab.bench/lab.stress/app.commands outside app.commands", offences, "")


def test_other_retrieval_layers_are_imported_through_their_package(modules):
    offences = facade_offences(modules)
    assert not offences, _report("imports that bypass a layer's __init__", offences, "see SUBMODULE_IMPORTS_ALLOWED")


def test_no_import_cycle(modules):
    cycle = cycle_in(modules)
    assert cycle is None, "module-level import cycle: " + " -> ".join(cycle)


def test_no_function_level_imports_without_a_reason(modules):
    offences = function_level_offences(modules)
    assert not offences, _report(
        "function-level imports of StoryBeam or third-party modules",
        offences,
        "move them to the top of the module, or say why on the line (or the line above): "
        "`# optional: pyrender (absent on Android)` / `# deferred: ...`",
    )


def test_no_private_names_imported_across_modules(modules):
    offences = private_offences(modules)
    assert not offences, _report("imports of another module's _private names", offences, "make the name public")


def test_packages_have_docstrings_and_curated_all(modules):
    offences = package_offences(modules)
    assert not offences, _report("package problems", offences, "")


@pytest.mark.parametrize("group", sorted(RUNTIME_FORBIDDEN))
def test_importing_a_package_loads_nothing_forbidden(group):
    include, skip, forbidden = RUNTIME_FORBIDDEN[group]
    names = sorted(
        name for name in discover(packages=sorted({p.split(".")[0] for p in include}))
        if any(name == p or name.startswith(p + ".") for p in include)
        and not any(name == s or name.startswith(s + ".") for s in skip)
    )
    code = (
        "import importlib, json, sys\n"
        f"for m in {names!r}: importlib.import_module(m)\n"
        "print(json.dumps(sorted({n.split('.')[0] for n in sys.modules})))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    loaded = set(json.loads(out.stdout.strip().splitlines()[-1]))
    bad = sorted(loaded & set(forbidden))
    assert not bad, f"importing every module of {group} ({len(names)} modules) loads {bad}"


def test_architecture_diagram_is_current():
    spec = importlib.util.spec_from_file_location("draw_architecture", REPO / "scripts" / "draw_architecture.py")
    draw = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(draw)
    doc = (REPO / "docs" / "design" / "architecture.md").read_text(encoding="utf-8")
    assert draw.BEGIN in doc and draw.END in doc, "docs/design/architecture.md lost its generated-diagram markers"
    assert doc == draw.update_document(doc, draw.mermaid(scan())), (
        "the diagram in docs/design/architecture.md no longer matches the imports: run python scripts/draw_architecture.py"
    )


#: The one module allowed to choose PyOpenGL's platform (before pyrender loads).
GL_PLATFORM_OWNER = "ar/render/__init__.py"
#: The modules allowed to turn ``__file__`` into paths into the checkout.
#: ar/body/models.py: the vendored pose models' folder (ar may not import app.paths, a higher layer).
PATH_OWNERS = ("app/paths.py", "retrieval/dtw/jit.py", "ar/body/models.py")


def one_place_offences(root: Path = REPO, packages: Iterable[str] = PACKAGES) -> list[str]:
    """Code (not comments or docstrings) that names ``PYOPENGL_PLATFORM`` outside
    :data:`GL_PLATFORM_OWNER`, or uses ``__file__`` outside :data:`PATH_OWNERS`."""
    out = []
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            rel = path.relative_to(root).as_posix()
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.Constant) and node.value == "PYOPENGL_PLATFORM" and rel != GL_PLATFORM_OWNER:
                    out.append(f"{rel}:{node.lineno}: sets or reads PYOPENGL_PLATFORM (only {GL_PLATFORM_OWNER} may)")
                if isinstance(node, ast.Name) and node.id == "__file__" and rel not in PATH_OWNERS:
                    out.append(f"{rel}:{node.lineno}: builds a path from __file__ (use app.paths)")
    return _dedupe(out)


def test_gl_platform_and_checkout_paths_are_chosen_in_one_place():
    offences = one_place_offences()
    assert not offences, _report("settings made outside their one place", offences,
                                 "import ar.render (it sets PYOPENGL_PLATFORM) / take paths from app.paths")


def test_checker_catches_settings_made_elsewhere(tmp_path):
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "a.py").write_text(textwrap.dedent('''\
        """Naming __file__ and PYOPENGL_PLATFORM in a docstring is fine."""
        import os
        from pathlib import Path
        os.environ["PYOPENGL_PLATFORM"] = "egl"
        HERE = Path(__file__)
        '''))
    assert one_place_offences(tmp_path, ["pkg"]) == [
        "pkg/a.py:4: sets or reads PYOPENGL_PLATFORM (only ar/render/__init__.py may)",
        "pkg/a.py:5: builds a path from __file__ (use app.paths)",
    ]


# --------------------------------------------------------------------------------------
# Self-tests: each checker fails on a package built to break it
# --------------------------------------------------------------------------------------

SYNTHETIC_UNITS = ("pkg", "pkg.low", "pkg.high")
SYNTHETIC_ALLOWED = {"pkg": (), "pkg.low": (), "pkg.high": ("pkg.low",)}


def _write(root: Path, files: Mapping[str, str], packages: tuple[str, ...] = ("pkg",)) -> dict[str, Module]:
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(text).lstrip(), encoding="utf-8")
    return scan(root, packages=packages)


@pytest.fixture()
def bad_package(tmp_path) -> tuple[Path, dict[str, Module]]:
    root = tmp_path
    return root, _write(
        root,
        {
            "pkg/__init__.py": '"""A synthetic package."""\n',
            "pkg/low/__init__.py": '"""Low layer."""\nfrom pkg.low.a import public\n__all__ = ["public", "missing"]\n',
            "pkg/low/a.py": """
                import numba
                from pkg.high.b import thing  # low imports high: against the layering (and a cycle)

                public = 1
                _secret = 2
            """,
            "pkg/high/__init__.py": "x = 1\n",
            "pkg/high/b.py": """
                from pkg.low.a import public, _secret

                thing = public + _secret


                def late():
                    import pkg.low.a
                    import json

                    # optional: kivy (absent on servers)
                    import kivy
                    from pkg.low import public  # deferred: breaks a start-up cost
                    return pkg.low.a, json, kivy, public
            """,
            "pkg/stray/c.py": "",
        },
    )


def test_checkers_catch_layer_violations(bad_package):
    root, modules = bad_package
    offences = layer_offences(modules, SYNTHETIC_ALLOWED, SYNTHETIC_UNITS, root)
    assert len(offences) == 1, offences
    assert offences[0].startswith("pkg/low/a.py:2: pkg.low.a (layer pkg.low) imports pkg.high.b (layer pkg.high)")
    assert not layer_offences(modules, {**SYNTHETIC_ALLOWED, "pkg.low": ("pkg.high",)}, SYNTHETIC_UNITS, root)


def test_checkers_catch_third_party_rules(bad_package):
    root, modules = bad_package
    offences = third_party_offences(modules, {"pkg.high": ("kivy",)}, {"numba": ("pkg.jit",)}, SYNTHETIC_UNITS, root)
    assert any(o.startswith("pkg/high/b.py:11: pkg.high.b (layer pkg.high) may not import kivy") for o in offences)
    assert any(o.startswith("pkg/low/a.py:1: numba is imported only by pkg.jit") for o in offences), offences
    assert len(offences) == 2, offences


def test_checkers_find_import_cycles(bad_package):
    root, modules = bad_package
    assert cycle_in(modules) == ["pkg.high.b", "pkg.low.a", "pkg.high.b"]
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]


def test_package_init_counts_as_importing_what_it_imports(tmp_path):
    """`from pkg import name` (an attribute) goes through pkg's __init__, which imports
    the module that imports back: a cycle, found."""
    modules = _write(
        tmp_path,
        {
            "pkg/__init__.py": '"""Pkg."""\nfrom pkg.a import f\n',
            "pkg/a.py": "from pkg.b import g\n\ndef f():\n    return g\n",
            "pkg/b.py": "from pkg import f\n\ndef g():\n    return f\n",
        },
    )
    assert cycle_in(modules) == ["pkg", "pkg.a", "pkg.b", "pkg"]


def test_checkers_catch_function_level_imports(bad_package):
    root, modules = bad_package
    offences = function_level_offences(modules, root)
    # `import json` is stdlib; `import kivy` and the `from pkg.low` import carry a reason
    assert offences == ["pkg/high/b.py:7: import pkg.low.a"], offences


def test_checkers_catch_private_imports(bad_package):
    root, modules = bad_package
    assert private_offences(modules, root) == ["pkg/high/b.py:1: pkg.high.b imports _secret from pkg.low.a"]


def test_checkers_catch_package_problems(bad_package):
    root, modules = bad_package
    offences = package_offences(modules, root, packages=("pkg",), curated=("pkg.",))
    assert "pkg/stray/: a folder of modules without an __init__.py" in offences
    assert "pkg/high/__init__.py:1: package pkg.high has no docstring" in offences
    assert "pkg/high/__init__.py: package pkg.high does not define __all__" in offences
    assert "pkg/low/__init__.py: __all__ of pkg.low lists 'missing', which it does not define" in offences
    assert len(offences) == 4, offences


def test_checkers_catch_imports_that_bypass_a_package(tmp_path):
    modules = _write(
        tmp_path,
        {
            "retrieval/__init__.py": '"""R."""\n',
            "retrieval/dtw/__init__.py": '"""D."""\nfrom retrieval.dtw.lower_bounds import k\n',
            "retrieval/dtw/lower_bounds.py": "k = 1\n",
            "retrieval/dtw/jit.py": "numba = None\n",
            "retrieval/search/__init__.py": '"""S."""\n',
            "retrieval/search/fast.py": "from retrieval.dtw.lower_bounds import k\nfrom retrieval.dtw import k as k2\n"
            "from retrieval.dtw.jit import numba\n",
        },
        packages=("retrieval",),
    )
    offences = facade_offences(modules, root=tmp_path)
    assert len(offences) == 1 and offences[0].startswith("retrieval/search/fast.py:1: retrieval.search.fast imports "
                                                         "retrieval.dtw.lower_bounds directly"), offences


def test_rules_name_only_known_units():
    for unit, allowed in ALLOWED.items():
        assert unit not in allowed, f"{unit} lists itself"
        assert set(allowed) <= set(UNITS), (unit, sorted(set(allowed) - set(UNITS)))
    assert set(FORBIDDEN_THIRD_PARTY) <= set(UNITS)
    for unit in ("retrieval.animation",):
        assert not {"retrieval.dtw", "retrieval.search", "retrieval.library", "lab.experiment"} & set(
            ALLOWED[unit]
        )
    assert all(is_storybeam(u) for u in UNITS)


#: The rig's frame loop has one definition, ar.rig.RigTracker.step (issue 30). Its parts
#: may be used outside ar/ only by these modules: (module, why).
RIG_LOOP_PARTS = ("RegionPoseEstimator", "estimate_board_pose", "solve_board_pose", "PoseTracker")
RIG_LOOP_PART_USERS = (
    ("lab.bench.ar", "the unfiltered poses' jitter and the detection before issue 13, timed beside the rig's"),
    ("lab.stress.tracking", "hands the rig a PoseTracker of its own settings (RigTracker(tracker=...)); never steps it"),
)


def rig_loop_offences(modules: Mapping[str, Module], users: Iterable[tuple[str, str]] = RIG_LOOP_PART_USERS,
                      root: Path = REPO) -> list[str]:
    """Imports of the frame loop's parts from outside ar/ by a module not in ``users``."""
    allowed = {name for name, _why in users}
    return _dedupe(f"{imp.describe(root)}: the rig's frame loop is ar.rig.RigTracker.step; step it instead"
                   for module in modules.values() if not module.name.startswith("ar.") and module.name != "ar"
                   and module.name not in allowed
                   for imp in module.imports if imp.name in RIG_LOOP_PARTS and imp.top == "ar")


def test_the_rig_frame_loop_has_one_definition(modules):
    assert not rig_loop_offences(modules), _report("the rig's frame loop rebuilt outside ar/",
                                                   rig_loop_offences(modules), "see RIG_LOOP_PART_USERS")


def test_checkers_catch_a_frame_loop_outside_ar(tmp_path):
    scanned = _write(tmp_path, {"ar/__init__.py": '"""A."""\n', "ar/pose.py": "class RegionPoseEstimator: ...\n",
                                "app/__init__.py": '"""B."""\n',
                                "app/stage.py": "from ar.pose import RegionPoseEstimator\n"}, ("ar", "app"))
    found = rig_loop_offences(scanned, (), tmp_path)
    assert len(found) == 1 and "app/stage.py:1" in found[0]
