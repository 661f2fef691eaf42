"""Every module the package imports at run time is the standard library, the package itself, or a
declared dependency of pyproject.toml (a plain `pip install .` must be able to run every method);
raytrace/rendering/distributed.py alone imports its optional extra's Dask."""
import ast
import re
import sys
import tomllib
from importlib.metadata import packages_distributions
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _name(requirement: str) -> str:
    return re.split(r"[<>=!~\[; ]", requirement, maxsplit=1)[0].lower().replace("_", "-")


def imported_modules():
    found = {}
    for path in sorted((ROOT / "raytrace").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                names = [node.module]
            else:
                continue
            for n in names:
                found.setdefault(n.split(".")[0], f"{path.relative_to(ROOT)}:{node.lineno}")
    return found


def test_every_runtime_import_is_a_declared_dependency():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    declared = {_name(r) for r in project["dependencies"]}
    optional = {"raytrace/rendering/distributed.py": {"dask", "distributed"},  # the extra dask[distributed] installs both
                "raytrace/experiments/seed002.py": {"matplotlib"}}  # the `plots` extra
    assert any(_name(r) == "matplotlib" for r in project["optional-dependencies"]["plots"])
    assert any(_name(r) == "dask" for r in project["optional-dependencies"]["distributed"])
    dists = packages_distributions()
    missing = []
    for module, where in imported_modules().items():
        extra = optional.get(where.split(":")[0], set())
        if module in sys.stdlib_module_names or module == "raytrace" or module in extra:
            continue
        names = {_name(d) for d in dists.get(module, [module])}
        if not names & declared:
            missing.append(f"{module} ({where}; distribution {sorted(names)})")
    assert not missing, "imported but not declared in [project] dependencies: " + ", ".join(missing)


def test_the_check_sees_scipy():
    """The check is not vacuous: the sun method's scipy import is found and must be declared."""
    assert "scipy" in imported_modules()
