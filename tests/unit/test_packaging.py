"""The package is installed under one name, ``vpcontact`` (pyproject.toml's package-dir
mapping of the folders app/, forms/ and meshes/), and importing it changes nothing in the
process: no environment variable, no MPI start-up, no heavy import."""
import os
import subprocess
import sys
import tomllib

from conftest import ROOT

FOLDERS = {"vpcontact": "app", "vpcontact.forms": "forms", "vpcontact.meshes": "meshes"}


def test_every_package_folder_is_installed():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert config["package-dir"] == FOLDERS
    found = set()
    for name, folder in FOLDERS.items():
        for init in (ROOT / folder).rglob("__init__.py"):
            found.add(".".join((name, *init.parent.relative_to(ROOT / folder).parts)))
    assert sorted(found) == sorted(config["packages"])


def _fresh_python(code: str, cwd) -> subprocess.CompletedProcess:
    """``code`` in a new interpreter whose working directory is not on sys.path."""
    return subprocess.run([sys.executable, "-P", "-c", code], cwd=cwd, capture_output=True,
                          text=True, timeout=120)


def test_only_vpcontact_is_importable(tmp_path):
    code = ("import importlib.util as u; "
            "print([n for n in ('vpcontact', 'app', 'forms', 'meshes') if u.find_spec(n)])")
    out = _fresh_python(code, tmp_path)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["['vpcontact']"]


def test_import_has_no_side_effects(tmp_path):
    code = ("import os, sys; env = dict(os.environ); before = set(sys.modules); "
            "import vpcontact; "
            "print(sorted(set(sys.modules) - before), env == dict(os.environ), "
            "vpcontact.__version__)")
    out = _fresh_python(code, tmp_path)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["['vpcontact']", "True", vpcontact_version()]


def vpcontact_version() -> str:
    """The version pyproject.toml reads from app/__init__.py (a literal)."""
    for line in (ROOT / "app" / "__init__.py").read_text().splitlines():
        if line.startswith("__version__"):
            return line.split("=")[1].strip().strip('"')
    raise AssertionError("no __version__ in app/__init__.py")


def test_the_api_names_load_on_first_use(tmp_path):
    code = ("import vpcontact; from vpcontact import Simulation, validate, FieldOutput; "
            "print(Simulation.__module__, validate.__module__, FieldOutput.__module__); "
            "print(sorted(vpcontact.__all__) == sorted(set(vpcontact.__all__)))")
    out = _fresh_python(code, tmp_path)
    assert out.returncode == 0, out.stderr
    *modules, unique = out.stdout.split()
    assert all(m.startswith("vpcontact.") for m in modules) and unique == "True"
    env_code = "import os; import vpcontact as v; print('OPENBLAS_NUM_THREADS' in os.environ)"
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    out = subprocess.run([sys.executable, "-P", "-c", env_code], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=120)
    assert out.stdout.split() == ["False"]
