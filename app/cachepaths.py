"""Where vpcontact and the libraries it drives keep their caches, and a usable replacement
when one of them is not writable (a read-only, missing or file-valued home directory).

- run and kernel cache (``CACHE_SEARCH``): $VPCONTACT_CACHE, else $XDG_CACHE_HOME/vpcontact,
  else ~/.cache/vpcontact (compiled kernels in its ``kernels`` subdirectory);
- FFCx JIT cache of dolfinx: $XDG_CACHE_HOME/fenics, else ~/.cache/fenics (dolfinx.jit reads
  it once, when it is imported);
- matplotlib's configuration directory: $MPLCONFIGDIR, else $XDG_CONFIG_HOME/matplotlib, else
  ~/.config/matplotlib (its font cache follows XDG_CACHE_HOME);
- user settings of FFCx and dolfinx, read from $XDG_CONFIG_HOME, else ~/.config: both stop on
  anything but a missing file there.

``prepare`` runs when the command line starts (app/io/cachedirs.py: ``start``), before
dolfinx: it writes a file into each cache directory. One that is not writable is replaced by
a directory under ``tempfile.gettempdir()/vpcontact-<uid>``, announced through the
environment (dolfinx, matplotlib and child processes read it there) and named in one warning
line.
"""
from __future__ import annotations

import os
import stat
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

CONFIG_FILES = (("ffcx", "ffcx_parameters.json"), ("dolfinx", "dolfinx_jit_parameters.json"))
XDG_VARS = ("XDG_CACHE_HOME", "XDG_CONFIG_HOME")
# The run and kernel cache as ``vpcontact_dir`` finds it, for help texts and messages.
CACHE_SEARCH = "$VPCONTACT_CACHE, else $XDG_CACHE_HOME/vpcontact, else ~/.cache/vpcontact"


class CacheUnusable(OSError):
    """No writable directory for a cache, not even a temporary one."""


@dataclass
class Caches:
    """The directories in use and the ones replaced.

    Attributes:
        root: the run and kernel cache.
        ffcx: dolfinx's FFCx JIT cache.
        replaced: (what, wanted, used, why not) of each directory replaced.
        ignored: (variable, value) of each XDG variable ignored (not an absolute path).
    """

    root: Path
    ffcx: Path
    replaced: list = field(default_factory=list)
    ignored: list = field(default_factory=list)     # (variable, value) not absolute

    @property
    def kernels(self) -> Path:
        """The compiled kernels' directory, ``kernels`` in the run cache."""
        return self.root / "kernels"

    def warnings(self) -> list[str]:
        """The warnings for the user, without the ``vpcontact: warning:`` prefix.

        Returns:
            One message per relative XDG variable ignored, and one naming each unusable
            directory and the one used instead; empty if there is nothing to say.
        """
        messages = [f"{var}={value!r} is not an absolute path, ignored (as the XDG base "
                    "directory specification asks)" for var, value in self.ignored if value]
        if self.replaced:
            parts = [f"{what} {wanted} ({why}) -> {used}"
                     for what, wanted, used, why in self.replaced]
            messages.append("not writable, using a temporary directory instead: "
                            + "; ".join(parts))
        return messages


def unusable(path: Path) -> str | None:
    """Whether a cache directory is usable (it is created if missing).

    Args:
        path: the directory.

    Returns:
        None if ``path`` is, or can be made, a directory this process can write a file into;
        else the reason it cannot (e.g. 'Read-only file system').
    """
    try:
        path.mkdir(parents=True, exist_ok=True)
        fd, name = tempfile.mkstemp(dir=path, prefix=".vpcontact-write-test-")
        os.close(fd)
        os.unlink(name)
    except FileExistsError:
        return "a file, not a directory"
    except OSError as exc:
        return exc.strerror or type(exc).__name__
    return None


def _home(env) -> Path:
    return Path(env["HOME"]) if env.get("HOME") else Path(os.path.expanduser("~"))


def vpcontact_dir(env) -> Path:
    """The run and kernel cache the environment asks for (``CACHE_SEARCH``).

    Args:
        env: the environment (a mapping); empty variables count as unset.

    Returns:
        The directory (not checked).
    """
    if env.get("VPCONTACT_CACHE"):
        return Path(env["VPCONTACT_CACHE"])
    if env.get("XDG_CACHE_HOME"):
        return Path(env["XDG_CACHE_HOME"]) / "vpcontact"
    return _home(env) / ".cache" / "vpcontact"


def ffcx_dir(env) -> Path:
    """dolfinx's FFCx cache, read the way dolfinx.jit reads it.

    Args:
        env: the environment (a mapping).

    Returns:
        $XDG_CACHE_HOME/fenics, else ~/.cache/fenics.
    """
    base = env["XDG_CACHE_HOME"] if "XDG_CACHE_HOME" in env else _home(env) / ".cache"
    return Path(base) / "fenics"


def _config_dir(env) -> Path:
    """$XDG_CONFIG_HOME, else ~/.config: read the way FFCx and dolfinx read it."""
    return Path(env["XDG_CONFIG_HOME"] if "XDG_CONFIG_HOME" in env else _home(env) / ".config")


def _config_unreadable(root: Path) -> str | None:
    """Why FFCx or dolfinx would fail to read their settings under ``root``, or None."""
    for sub, name in CONFIG_FILES:
        try:
            open(root / sub / name, "rb").close()
        except FileNotFoundError:
            continue
        except OSError as exc:
            return exc.strerror or type(exc).__name__
    return None


def fallback_base() -> Path:
    """The base of the replacement caches, a directory of this user only.

    Returns:
        tempfile.gettempdir()/vpcontact-<uid>, created with mode 0700.

    Raises:
        CacheUnusable: if it cannot be created or is not a directory of this user.
    """
    try:
        base = Path(tempfile.gettempdir()) / f"vpcontact-{os.getuid()}"
    except OSError as exc:                  # no usable temporary directory at all
        raise CacheUnusable(exc.strerror) from None
    try:
        base.mkdir(mode=0o700, exist_ok=True)
        st = os.lstat(base)
    except OSError as exc:
        raise CacheUnusable(f"{base} ({exc.strerror})") from None
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid():
        raise CacheUnusable(f"{base} (not a directory of this user)")
    return base


def _replace(env, replaced: list, what: str, wanted: Path, why: str, var: str,
             sub: str) -> Path:
    """Put the cache ``what`` into fallback_base()/sub and point ``var`` at it."""
    try:
        base = fallback_base()
    except CacheUnusable as exc:
        raise CacheUnusable(f"no writable {what} directory: {wanted} ({why}), {exc}; set {var} "
                            "to a writable directory") from None
    used = base / sub
    reason = unusable(used)
    if reason:
        raise CacheUnusable(f"no writable {what} directory: {wanted} ({why}), {used} "
                            f"({reason}); set {var} to a writable directory")
    env[var] = str(base if var == "XDG_CACHE_HOME" else used)
    replaced.append((what, wanted, used, why))
    return used


def prepare(env=None) -> Caches:
    """Test every cache and settings directory and replace the unusable ones.

    Args:
        env: the environment, updated in place (default os.environ).

    Returns:
        The directories in use.

    Raises:
        CacheUnusable: if a replacement is not writable either.
    """
    env = os.environ if env is None else env
    replaced: list = []
    # empty or relative XDG values are invalid (XDG base directory specification): removed,
    # so that dolfinx, FFCx and matplotlib, which read them too, use the home directory's
    ignored = [(var, env.pop(var)) for var in XDG_VARS
               if var in env and not os.path.isabs(env[var])]
    cfg = _config_dir(env)
    why = _config_unreadable(cfg)
    if why:
        _replace(env, replaced, "settings", cfg, why, "XDG_CONFIG_HOME", "config")
    root = vpcontact_dir(env)
    why = unusable(root)
    if why:
        root = _replace(env, replaced, "cache", root, why, "VPCONTACT_CACHE", "vpcontact")
    ffcx = ffcx_dir(env)
    why = unusable(ffcx)
    if why:
        ffcx = _replace(env, replaced, "FFCx cache", ffcx, why, "XDG_CACHE_HOME", "fenics")
    mpl = Path(env["MPLCONFIGDIR"]) if env.get("MPLCONFIGDIR") else \
        _config_dir(env) / "matplotlib"
    why = unusable(mpl)
    if why:
        _replace(env, replaced, "matplotlib", mpl, why, "MPLCONFIGDIR", "matplotlib")
    return Caches(root, ffcx, replaced, ignored)


_CACHES: Caches | None = None


def caches() -> Caches:
    """The directories in use (prepared once per process).

    Returns:
        The Caches of this process.
    """
    global _CACHES
    if _CACHES is None:
        _CACHES = prepare()
    return _CACHES


def prepare_caches() -> Caches:
    """Prepare the directories anew (``prepare``) and keep them for ``caches``.

    Returns:
        The Caches of this process.

    Raises:
        CacheUnusable: if a replacement is not writable either.
    """
    global _CACHES
    _CACHES = prepare()
    return _CACHES


def cache_root() -> Path:
    """The run cache (convergence study); compiled kernels go to its ``kernels``.

    Returns:
        The directory (``CACHE_SEARCH``, or its replacement).
    """
    return caches().root
