"""One import package: installing gelrig adds exactly one top-level import name, ``gelrig``,
and no source file imports the repository's folders by their bare names (which work from a
checkout, where the folders sit on sys.path, and break once installed)."""

import ast
import os
import shutil
import subprocess
import sys
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FOLDERS = ("instrument", "drivers", "simulators", "protocols", "gui")


def python_files() -> list[Path]:
    """Every tracked Python file (git tracks the links under gelrig/ as links)."""
    listed = subprocess.run(["git", "ls-files", "*.py"], cwd=ROOT, check=True,
                            capture_output=True, text=True).stdout.split()
    return [ROOT / name for name in listed]


def test_the_folders_are_linked_under_the_one_package():
    for folder in FOLDERS:
        link = ROOT / "gelrig" / folder
        assert link.is_symlink() and link.resolve() == (ROOT / folder).resolve(), folder


def test_no_source_imports_a_folder_by_its_bare_name():
    bare = []
    files = python_files()
    assert len(files) > 100
    for path in files:
        tree = ast.parse(path.read_text(encoding="utf-8-sig"), str(path))
        for node in ast.walk(tree):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                     [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level
                     else [])
            bare += [f"{path.relative_to(ROOT)}:{node.lineno}: {name}" for name in names
                     if name.split(".")[0] in FOLDERS]
    assert bare == []


@pytest.mark.slow
def test_an_installed_gelrig_adds_only_the_gelrig_import_name(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}  # the fresh venv only
    source = tmp_path / "source"  # a copy: a build leaves build/ and *.egg-info behind
    skip = shutil.ignore_patterns("__pycache__", "*.pyc")
    for name in ("gelrig", *FOLDERS):
        shutil.copytree(ROOT / name, source / name, symlinks=True, ignore=skip)
    for name in ("pyproject.toml", "README.md"):
        shutil.copyfile(ROOT / name, source / name)
    wheels = tmp_path / "wheels"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps",
                    "--no-build-isolation", "-w", str(wheels), str(source)], check=True,
                   capture_output=True)
    wheel = next(wheels.glob("gelrig-*.whl"))
    fresh = tmp_path / "fresh"
    venv.create(fresh, with_pip=True)
    python = fresh / "bin" / "python"
    subprocess.run([str(python), "-m", "pip", "install", "--quiet", "--no-deps", "--no-index",
                    str(wheel)], check=True, capture_output=True, env=env)
    out = subprocess.run(
        [str(python), "-c", "import importlib.metadata as m, json; print(json.dumps("
         "sorted(k for k, v in m.packages_distributions().items() if 'gelrig' in v)))"],
        check=True, capture_output=True, text=True, cwd=tmp_path, env=env).stdout
    assert out.strip() == '["gelrig"]'
    shipped = subprocess.run(
        [str(python), "-c", "import importlib.util as u, pathlib; p = pathlib.Path("
         "u.find_spec('gelrig').origin).parent; print(p.is_relative_to(pathlib.Path("
         "__import__('sys').prefix)), (p / 'instrument' / 'core' / 'clock.py').is_file(), "
         "(p / 'protocols' / 'rigs' / 'compression.toml').is_file())"],
        check=True, capture_output=True, text=True, cwd=tmp_path, env=env).stdout
    assert shipped.split() == ["True", "True", "True"]  # the folders' files, inside gelrig


#: What each part may import of gelrig (design.md, ADR 0001): its own part and these.
ALLOWED = {
    "instrument.core": set(),
    "instrument.contracts": {"instrument.core"},
    "instrument.physics": {"instrument.core"},
    "instrument.analysis": {"instrument.core", "instrument.physics"},
    "instrument.reports": {"instrument.core", "instrument.physics", "instrument.analysis"},
    # a simulator may reuse a driver's wire codec when an independent client drives it too
    "simulators": {"instrument", "drivers.mcr501.codec", "drivers.mcr501.commands",
                   "drivers.kdc101.apt", "drivers.kdc101.payloads"},
    "drivers": {"instrument"},
    "protocols": {"instrument"},
    # the results browser reads runs through the same query and comparison as `gelrig runs`
    # (issue 28), two read-only modules of the root: a recorded deviation, ADR 0383
    "gui": {"protocols", "instrument", "catalog", "compare"},
}


def part_of(module: str) -> str | None:
    """The part (key of ALLOWED) a ``gelrig.*`` module belongs to, or None (a root)."""
    name = module.removeprefix("gelrig.")
    return next((p for p in sorted(ALLOWED, key=len, reverse=True)
                 if name == p or name.startswith(p + ".")), None)


def test_every_part_imports_only_downwards():
    """No arrow up and no cycle between parts: the composition roots (gelrig/ itself) may
    import everything, the parts only what ALLOWED lists, lazy imports included."""
    wrong = []
    for path in python_files():
        rel = path.relative_to(ROOT)
        if rel.parts[0] not in FOLDERS or (rel.parts[-1] == "__init__.py" and len(rel.parts) == 2):
            continue
        here = part_of(".".join(("gelrig", *rel.with_suffix("").parts)))
        assert here is not None, rel
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8-sig"), str(path))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                     [f"{node.module}.{a.name}" for a in node.names]
                     if isinstance(node, ast.ImportFrom) and not node.level else [])
            for name in names:
                if not name.startswith("gelrig."):
                    continue
                there = name.removeprefix("gelrig.")
                if part_of(name) == here:
                    continue
                if not any(there == a or there.startswith(a + ".") for a in ALLOWED[here]):
                    wrong.append(f"{rel}:{node.lineno}: {here} imports {name}")
    assert wrong == []
