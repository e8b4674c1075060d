"""Import layering of the package.

The calibration and selection toolkits must run without the finite-element (FE) stack (numba
kernels, model, elements, contact, integrators, scenarios, consignment builders); the domain code
must not depend on the toolkits, the command line or the plots. Checked two ways: a fresh
interpreter imports the toolkits and must not load the FE modules, and every module under
src/flexparcel is parsed with :mod:`ast` (all import statements, those inside functions included,
and ``importlib.import_module`` calls with a literal name) and its imports checked against the
rules below.
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from functools import cache
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
PACKAGE = "flexparcel"

# The finite-element stack. ``flexparcel.consignments`` is a lazy package whose ``spec`` module
# needs only the standard library: both are allowed to the toolkits (an eager package __init__
# would show up as an import of the builders and fail the check).
FE = (
    "model",
    "builder",
    "elements",
    "contact",
    "integrate",
    "simulate",
    "scenarios",
    "consignments",
)
FE_ALLOWED = {f"{PACKAGE}.consignments", f"{PACKAGE}.consignments.spec"}
FE_EXTERNAL = {"numba"}
TOOLKITS = ("calibration", "selection")
DOMAIN = (
    "model",
    "elements",
    "contact",
    "integrate",
    "simulate",
    "io",
    "consignments",
    "scenarios",
)
PHYSICS = (
    "model",
    "builder",
    "elements",
    "contact",
    "integrate",
    "simulate",
    "consignments",
    "scenarios",
)
FRONT_ENDS = ("selection", "cli", "viz")


def _in(module: str, packages: tuple[str, ...]) -> bool:
    """``module`` is one of ``flexparcel.<p>`` or below it, for p in ``packages``."""
    return any(module == f"{PACKAGE}.{p}" or module.startswith(f"{PACKAGE}.{p}.") for p in packages)


def _is_fe(module: str) -> bool:
    return module in FE_EXTERNAL or (_in(module, FE) and module not in FE_ALLOWED)


@cache
def _sources() -> dict[str, Path]:
    """Module name -> file, for every module of the package."""
    out = {}
    for path in sorted((SRC / PACKAGE).rglob("*.py")):
        parts = path.relative_to(SRC).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


@cache
def _lazy_names() -> dict[str, str]:
    """The package's public name -> module map (``flexparcel._LAZY``), read without importing."""
    tree = ast.parse(_sources()[PACKAGE].read_text(encoding="utf-8"))
    for node in tree.body:
        target = node.target if isinstance(node, ast.AnnAssign) else None
        if isinstance(node, ast.Assign) and len(node.targets) == 1:
            target = node.targets[0]
        if isinstance(target, ast.Name) and target.id == "_LAZY":
            return ast.literal_eval(node.value)
    raise AssertionError("flexparcel/__init__.py has no _LAZY map")


def _resolve_from(module: str, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    is_package = _sources()[module].name == "__init__.py"
    base = module.split(".")
    base = base[: len(base) - node.level + (1 if is_package else 0)]
    return ".".join(base + ([node.module] if node.module else []))


@cache
def _imports(module: str) -> frozenset[tuple[str, int]]:
    """(imported module, line) for every import in ``module``'s source, at any depth."""
    modules = _sources()
    found = set()
    for node in ast.walk(ast.parse(modules[module].read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found.update((alias.name, node.lineno) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = _resolve_from(module, node)
            for alias in node.names:
                if f"{base}.{alias.name}" in modules:
                    found.add((f"{base}.{alias.name}", node.lineno))
                elif base == PACKAGE and alias.name in _lazy_names():
                    found.add((_lazy_names()[alias.name], node.lineno))
                else:
                    found.add((base, node.lineno))
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr == "import_module"
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and isinstance(node.args[0].value, str)
        ):
            found.add((node.args[0].value, node.lineno))
    return frozenset(found)


def _with_parents(name: str) -> list[str]:
    """``a.b.c`` -> [a.b.c, a.b, a]: importing a module runs its packages' __init__ first."""
    parts = name.split(".")
    return [".".join(parts[:i]) for i in range(len(parts), 0, -1)]


def _reach(start: str) -> dict[str, list[str]]:
    """Every module ``start`` imports directly or through other modules of the package, with
    one import chain to it (``file:line`` per step)."""
    modules = _sources()
    chains: dict[str, list[str]] = {start: []}
    todo = [start]
    while todo:
        current = todo.pop()
        for target, line in sorted(_imports(current)):
            step = f"{modules[current].relative_to(SRC)}:{line} imports {target}"
            for name in _with_parents(target):
                if name in chains:
                    continue
                chains[name] = chains[current] + [step]
                if name in modules:
                    todo.append(name)
    return chains


def _direct(packages: tuple[str, ...], forbidden) -> list[str]:
    """``file:line imports X`` for each direct import of a forbidden module by a module of
    ``packages``."""
    modules = _sources()
    bad = []
    for module, path in modules.items():
        if not _in(module, packages):
            continue
        for target, line in sorted(_imports(module)):
            if forbidden(target):
                bad.append(f"{path.relative_to(SRC)}:{line} imports {target}")
    return bad


def _transitive(packages: tuple[str, ...], forbidden) -> list[str]:
    """One import chain per module of ``packages`` that reaches a forbidden module."""
    bad = []
    for module in _sources():
        if not _in(module, packages):
            continue
        for target, chain in sorted(_reach(module).items()):
            if target != module and forbidden(target):
                bad.append(" -> ".join(chain))
                break
    return bad


# --------------------------------------------------------------------------- the parser itself
def test_the_import_parser_sees_the_package():
    # Guards the rules below against passing vacuously (no modules found, imports missed).
    modules = _sources()
    assert len(modules) > 50 and f"{PACKAGE}.calibration.study" in modules
    imports = {t for t, _ in _imports(f"{PACKAGE}.consignments.build")}
    assert {f"{PACKAGE}.consignments.spec", f"{PACKAGE}.model.materials", "numpy"} <= imports
    # from-imports of submodules, function-level imports and the lazy public names
    assert f"{PACKAGE}.model.mesh" in {t for t, _ in _imports(f"{PACKAGE}.verification")}
    assert f"{PACKAGE}.calibration.report" in {
        t for t, _ in _imports(f"{PACKAGE}.calibration.study")
    }
    assert _lazy_names()["ModelBuilder"].startswith(f"{PACKAGE}.")
    assert any(_in(m, ("model",)) for m in _reach(f"{PACKAGE}.io.checkpoint"))


# --------------------------------------------------------------------------- the rules
def test_toolkits_do_not_load_the_fe_stack_at_run_time():
    code = (
        "import json, sys\n"
        "import flexparcel.calibration, flexparcel.selection\n"
        "import flexparcel.selection.export, flexparcel.consignments.spec\n"
        "print(json.dumps(sorted(sys.modules)))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    )
    loaded = json.loads(out.stdout.strip().splitlines()[-1])
    banned = [f"{PACKAGE}.{p}" for p in FE if p != "consignments"]
    banned += [f"{PACKAGE}.consignments.build", f"{PACKAGE}.consignments.assembly", "numba"]
    hit = [m for m in loaded if any(m == b or m.startswith(b + ".") for b in banned)]
    assert not hit, f"importing the toolkits loaded {hit}"


def test_public_names_load_on_first_use():
    # ``import flexparcel`` loads no FE code; every public name then resolves, and a submodule
    # of the same name (flexparcel.simulate) does not shadow the public function.
    code = (
        "import sys\n"
        "import flexparcel as fp\n"
        "assert 'flexparcel.model' not in sys.modules and 'numba' not in sys.modules\n"
        "import flexparcel.simulate\n"
        "assert callable(fp.simulate) and fp.simulate.__name__ == 'simulate'\n"
        "missing = [n for n in fp.__all__ if getattr(fp, n, None) is None]\n"
        "assert not missing, missing\n"
        "assert set(fp.__all__) <= set(dir(fp))\n"
        "from flexparcel import ModelBuilder, mesh\n"
        "assert ModelBuilder is fp.ModelBuilder and mesh.__name__ == 'flexparcel.model.mesh'\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=300)


def test_toolkits_import_no_fe_code():
    # Directly or through other modules of the package (io.checkpoint -> model, say); the
    # calibration simulators that run the FE are found by name at call time instead.
    bad = _transitive(TOOLKITS, _is_fe)
    assert not bad, "calibration/selection reach the FE stack:\n" + "\n".join(bad)


def test_domain_imports_nothing_from_selection_cli_viz():
    bad = _direct(DOMAIN, lambda m: _in(m, FRONT_ENDS))
    assert not bad, "domain code imports a front end:\n" + "\n".join(bad)


def test_physics_reaches_no_cli_or_viz():
    # Through any chain of the package's modules, not only directly.
    bad = _transitive(PHYSICS, lambda m: _in(m, ("cli", "viz")))
    assert not bad, "physics code reaches cli/viz:\n" + "\n".join(bad)


def test_model_imports_no_elements_or_contact():
    bad = _direct(("model",), lambda m: _in(m, ("elements", "contact")))
    assert not bad, "model imports element/contact code:\n" + "\n".join(bad)


def test_no_two_modules_import_each_other():
    # a pair of modules that import each other (at any depth, even inside a function) is a
    # file cycle: neither can be read, tested or replaced alone. Packages' __init__ files
    # (lazy name maps) are left out: they name their own submodules by design.
    modules = _sources()
    plain = {m for m, path in modules.items() if path.name != "__init__.py"}
    direct = {m: {t for t, _ in _imports(m)} & plain for m in plain}
    pairs = sorted({tuple(sorted((a, b))) for a in plain for b in direct[a] if a in direct[b]})
    assert not pairs, "modules importing each other:\n" + "\n".join(
        f"{a} <-> {b}" for a, b in pairs
    )
