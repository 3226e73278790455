"""app/cachepaths.py (and app/io/cachedirs.py, which prints its warning): one definition of
every cache directory, and a temporary replacement for the ones that are not writable.
Unwritable paths lie under a regular file (mkdir fails there for root as well)."""
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from vpcontact import cachepaths
from vpcontact.io import cachedirs


@pytest.fixture
def tmp_root(tmp_path, monkeypatch):
    """tempfile.gettempdir() inside tmp_path, and a regular file to put paths under."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    (tmp_path / "file").write_text("not a directory")
    return tmp_path


def test_precedence_of_the_run_cache(tmp_path):
    home = {"HOME": str(tmp_path / "h")}
    assert cachepaths.vpcontact_dir(home) == tmp_path / "h" / ".cache" / "vpcontact"
    xdg = {**home, "XDG_CACHE_HOME": str(tmp_path / "x")}
    assert cachepaths.vpcontact_dir(xdg) == tmp_path / "x" / "vpcontact"
    own = {**xdg, "VPCONTACT_CACHE": str(tmp_path / "v")}
    assert cachepaths.vpcontact_dir(own) == tmp_path / "v"
    assert cachepaths.vpcontact_dir({**xdg, "VPCONTACT_CACHE": ""}) == tmp_path / "x" / "vpcontact"


def test_the_run_cache_is_described_once():
    """The convergence command's --cache-dir help says what vpcontact_dir does."""
    out = subprocess.run([sys.executable, "-m", "vpcontact", "convergence", "--help"],
                         capture_output=True, text=True, check=True).stdout
    assert cachepaths.CACHE_SEARCH in " ".join(out.split())


def test_ffcx_cache_is_where_dolfinx_puts_it():
    from dolfinx.jit import DOLFINX_DEFAULT_JIT_PARAMETERS
    assert cachepaths.ffcx_dir(os.environ) == Path(DOLFINX_DEFAULT_JIT_PARAMETERS["cache_dir"][0])
    assert cachepaths.caches().ffcx == cachepaths.ffcx_dir(os.environ)


def test_the_caches_in_use_are_one_definition(tmp_path):
    """Kernels, run cache, `info` and dolfinx agree, with XDG_CACHE_HOME set as well."""
    code = ("from vpcontact import kernels; from vpcontact.studies import runcache; "
            "from vpcontact.cli import checkrun; from dolfinx import jit; "
            "print(kernels.cache_dir()); print(runcache.default_cache_dir()); "
            "print(jit.DOLFINX_DEFAULT_JIT_PARAMETERS['cache_dir'][0]); "
            "print(*checkrun.info(), sep='\\n')")
    env = {k: v for k, v in os.environ.items() if k != "VPCONTACT_CACHE"}
    env["XDG_CACHE_HOME"] = str(tmp_path / "xdg")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True).stdout.splitlines()
    root = tmp_path / "xdg" / "vpcontact"
    assert out[:3] == [str(root / "kernels"), str(root), str(tmp_path / "xdg" / "fenics")]
    assert f"run cache (convergence study): {root}" in out
    assert f"JIT cache (FFCx): {tmp_path / 'xdg' / 'fenics'}" in out


def test_writable_directories_are_kept(tmp_root):
    env = {"HOME": str(tmp_root / "home")}
    caches = cachepaths.prepare(env)
    assert caches.replaced == [] and cachedirs.warning_text(caches) is None
    assert env == {"HOME": str(tmp_root / "home")}
    assert caches.root == tmp_root / "home" / ".cache" / "vpcontact" and caches.root.is_dir()
    assert caches.ffcx == tmp_root / "home" / ".cache" / "fenics"


@pytest.mark.parametrize("home", ["file/home", "file"])
def test_unusable_home_is_replaced_with_one_warning(tmp_root, home):
    """A home under a regular file, or a home that is a file (HOME=/dev/null)."""
    env = {"HOME": str(tmp_root / home)}
    caches = cachepaths.prepare(env)
    base = tmp_root / "tmp" / f"vpcontact-{os.getuid()}"
    assert caches.root == base / "vpcontact" and caches.ffcx == base / "fenics"
    assert env["XDG_CACHE_HOME"] == str(base)       # dolfinx reads base/fenics from it
    assert env["VPCONTACT_CACHE"] == str(base / "vpcontact")
    assert env["XDG_CONFIG_HOME"] == str(base / "config")   # FFCx/dolfinx would stop on it
    assert "MPLCONFIGDIR" not in env                # matplotlib: base/config/matplotlib
    assert cachepaths.vpcontact_dir(env) == caches.root   # what child processes will find
    assert cachepaths.ffcx_dir(env) == caches.ffcx
    line = cachedirs.warning_text(caches)
    assert "\n" not in line and line.startswith("vpcontact: warning: ")
    for _what, wanted, used, _ in caches.replaced:
        assert f"{wanted} (" in line and f"-> {used}" in line
    assert str(tmp_root / home / ".cache" / "fenics") in line
    assert oct(base.stat().st_mode & 0o777) == "0o700"


def test_unwritable_matplotlib_directory_is_replaced(tmp_root):
    env = {"HOME": str(tmp_root / "home"), "MPLCONFIGDIR": str(tmp_root / "file" / "mpl")}
    caches = cachepaths.prepare(env)
    base = tmp_root / "tmp" / f"vpcontact-{os.getuid()}"
    assert [r[0] for r in caches.replaced] == ["matplotlib"]
    assert env["MPLCONFIGDIR"] == str(base / "matplotlib")


def test_only_the_unusable_cache_is_replaced(tmp_root):
    env = {"HOME": str(tmp_root / "home"), "VPCONTACT_CACHE": str(tmp_root / "file" / "c")}
    caches = cachepaths.prepare(env)
    assert [r[0] for r in caches.replaced] == ["cache"]
    assert caches.ffcx == tmp_root / "home" / ".cache" / "fenics"
    assert "XDG_CACHE_HOME" not in env


def test_nothing_writable_is_one_clear_error(tmp_root):
    (tmp_root / "tmp" / f"vpcontact-{os.getuid()}").write_text("taken")
    env = {"HOME": str(tmp_root / "file" / "home")}
    with pytest.raises(cachepaths.CacheUnusable) as err:
        cachepaths.prepare(env)
    text = str(err.value)
    assert "\n" not in text and text.startswith("no writable ")
    assert str(tmp_root / "file" / "home") in text and "to a writable directory" in text


def test_unusable_says_why(tmp_root):
    assert cachepaths.unusable(tmp_root / "new" / "dir") is None
    assert cachepaths.unusable(tmp_root / "file") == "a file, not a directory"
    assert cachepaths.unusable(tmp_root / "file" / "sub") == "Not a directory"
