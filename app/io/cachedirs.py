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

``prepare`` runs when the package is imported (app/__init__.py), before dolfinx: it writes a
file into each cache directory.  One that is not writable is replaced by a directory under
``tempfile.gettempdir()/vpcontact-<uid>``, announced through the environment (dolfinx,
matplotlib and child processes read it there) and named in one warning line.
"""
from __future__ import annotations

import functools
import importlib.abc
import importlib.machinery
import os
import shutil
import stat
import struct
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from vpcontact.io.messages import EXIT_FAILED, error, warning, warning_line

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

    def warning(self) -> str | None:
        """The warning lines as printed (see ``warnings``).

        Returns:
            The lines, joined by newlines; None if there is nothing to say.
        """
        return "\n".join(warning_line(m) for m in self.warnings()) or None


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


def cache_root() -> Path:
    """The run cache (convergence study); compiled kernels go to its ``kernels``.

    Returns:
        The directory (``CACHE_SEARCH``, or its replacement).
    """
    return caches().root


def start(rank: int) -> None:
    """At import of the package: prepare the caches; rank 0 prints the warning, if any.

    With no writable directory at all, the one-line error and exit code 1 (an environmental
    fault, like a full disk).

    Args:
        rank: this process's MPI rank.

    Raises:
        SystemExit: (1) if no writable directory could be found for a cache.
    """
    global _CACHES
    try:
        _CACHES = prepare()
    except CacheUnusable as exc:
        raise SystemExit(error(str(exc), EXIT_FAILED, rank)) from None
    for message in _CACHES.warnings():
        warning(message, rank)
    install_jit_repair()


# --- damaged entries of the FFCx JIT cache --------------------------------------------------
# FFCx 0.5 (ffcx/codegeneration/jit.py, get_cached_module) loads an entry whose ``<name>.c``
# exists once ``<name>.c.cached`` says its compilation finished.  A library truncated by a
# full disk or a killed compilation either fails to load ("file too short", "invalid ELF
# header") or, worse, loads and dies with SIGBUS when the pages beyond its end are touched;
# a ``.c`` whose compilation never finished makes FFCx wait and time out.  ``repair_jit``
# checks an entry before FFCx loads it, and discards a damaged one so that FFCx compiles it
# again (under mpirun only rank 0 compiles, dolfinx.jit.mpi_jit_decorator; the other ranks
# load its result).

# the files of one entry besides the library: source, "ready" mark, failed source, object
JIT_ENTRY_SUFFIXES = (".c", ".c.cached", ".c.failed", ".o")
# an entry without its "ready" mark whose files are older than this is a dead compilation
JIT_STALE_SECONDS = 60.0
_JIT_DAMAGED: JitCacheError | None = None    # rank 0's, for the other ranks' message
_JIT_REPAIRED: set = set()                      # the cache directories warned about
_ELF_HEADER = struct.Struct("<16sHHIQQQIHHHHHH")    # Elf64_Ehdr (little endian)
_ELF_PHDR = struct.Struct("<IIQQQQQQ")               # Elf64_Phdr
_PT_LOAD = 1
# the platforms whose libraries are 64-bit little-endian ELF files (x86_64, aarch64 Linux)
_ELF_PLATFORM = sys.platform.startswith("linux") and sys.byteorder == "little" and \
    struct.calcsize("P") == 8


class JitCacheError(CacheUnusable):
    """The FFCx JIT cache cannot serve a form: a damaged entry that cannot be removed, a
    compilation that does not finish, or one that fails for want of space or of a working
    C compiler (one line, naming the directory)."""


def elf_damage(path: Path) -> str | None:
    """Why a compiled library cannot be loaded safely, read from its ELF headers.

    A library cut short keeps a valid header whose segments reach beyond the end of the
    file: the dynamic loader maps them and the process dies with SIGBUS on first use.

    Args:
        path: the ``.so`` file.

    Returns:
        None for a 64-bit little-endian ELF file whose loadable segments and section table
        lie inside the file; else the reason (empty, not ELF, truncated, unreadable).  On
        other platforms only an empty or unreadable file is a reason.
    """
    if not _ELF_PLATFORM:
        try:
            return None if os.path.getsize(path) else "an empty file"
        except OSError as exc:
            return f"unreadable ({exc.strerror or type(exc).__name__})"
    try:
        with open(path, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            head = f.read(_ELF_HEADER.size)
            if not head:
                return "an empty file"
            if len(head) < _ELF_HEADER.size or not head.startswith(b"\x7fELF\x02\x01"):
                return "not a 64-bit ELF library"
            fields = _ELF_HEADER.unpack(head)
            phoff, shoff, phentsize, phnum, shentsize, shnum = (
                fields[5], fields[6], fields[9], fields[10], fields[11], fields[12])
            if shoff + shentsize * shnum > size or phoff + phentsize * phnum > size:
                return f"truncated ({size} bytes)"
            f.seek(phoff)
            for _ in range(phnum):
                p_type, _, p_offset, _, _, p_filesz, _, _ = _ELF_PHDR.unpack(
                    f.read(phentsize)[:_ELF_PHDR.size])
                if p_type == _PT_LOAD and p_offset + p_filesz > size:
                    return f"truncated ({size} bytes)"
    except OSError as exc:
        return f"unreadable ({exc.strerror or type(exc).__name__})"
    except struct.error:
        return "not a 64-bit ELF library"
    return None


def _jit_entry(cache_dir: Path, module_name: str) -> list[Path]:
    """The existing files of one FFCx cache entry (libraries: any extension suffix Python loads)."""
    names = [module_name + s for s in JIT_ENTRY_SUFFIXES]
    names += [module_name + s for s in importlib.machinery.EXTENSION_SUFFIXES]
    return [cache_dir / n for n in names if os.path.lexists(cache_dir / n)]


def jit_entry_damage(cache_dir: Path, module_name: str, now: float | None = None) -> str | None:
    """Why an FFCx cache entry must be compiled again, judged before FFCx looks at it.

    Args:
        cache_dir: the FFCx cache directory.
        module_name: the entry (``libffcx_forms_<hash>``).
        now: the current time (default time.time()), for the age of an unfinished entry.

    Returns:
        None if the entry is absent, sound, or being compiled (younger than
        ``JIT_STALE_SECONDS``); else the reason.
    """
    files = _jit_entry(cache_dir, module_name)
    source = cache_dir / f"{module_name}.c"
    if source not in files:
        return None
    if cache_dir / f"{module_name}.c.cached" not in files:
        try:
            newest = max(os.lstat(p).st_mtime for p in files)
        except OSError:
            return None
        age = (time.time() if now is None else now) - newest
        return f"its compilation never finished ({age:.0f} s ago)" \
            if age > JIT_STALE_SECONDS else None
    libraries = [p for p in files if p.name[len(module_name):]
                 in importlib.machinery.EXTENSION_SUFFIXES]
    if not libraries:
        return "the compiled library is missing"
    for library in libraries:
        why = elf_damage(library)
        if why:
            return f"{library.name}: {why}"
    return None


def discard_jit_entry(cache_dir: Path, module_name: str) -> None:
    """Remove the files of an FFCx cache entry, so that FFCx compiles it again.

    Args:
        cache_dir: the FFCx cache directory.
        module_name: the entry.

    Raises:
        JitCacheError: if a file cannot be removed (the line names the directory).
    """
    for path in _jit_entry(cache_dir, module_name):
        try:
            if path.is_dir() and not path.is_symlink():
                shutil.rmtree(path)
            else:
                path.unlink()
        except FileNotFoundError:
            continue
        except OSError as exc:
            raise _damaged(
                f"the FFCx JIT cache entry {module_name} is damaged and cannot be removed "
                f"({path.name}: {exc.strerror or type(exc).__name__}); delete the directory "
                f"{cache_dir} (it is rebuilt) or set XDG_CACHE_HOME to another directory") \
                from None


def _damaged(message: str) -> JitCacheError:
    """The error, kept for the other ranks (under mpirun dolfinx keeps its text on rank 0 only)."""
    global _JIT_DAMAGED
    _JIT_DAMAGED = JitCacheError(message)
    return _JIT_DAMAGED


def repairing(get_cached_module):
    """FFCx's ``get_cached_module`` that compiles a damaged entry again instead of loading
    it, and says so in one warning line (the first damaged entry of a directory).

    Args:
        get_cached_module: ffcx.codegeneration.jit.get_cached_module.

    Returns:
        The replacement, with the same signature and results: (objects, module) of a cached
        entry, (None, None) when this process is to compile it.
    """
    @functools.wraps(get_cached_module)
    def get_cached(module_name, object_names, cache_dir, timeout):
        cache_dir = Path(cache_dir)
        why = jit_entry_damage(cache_dir, module_name)
        if why is None:
            try:
                return get_cached_module(module_name, object_names, cache_dir, timeout)
            except TimeoutError:                # another compilation may still be running
                raise _damaged(
                    f"the FFCx JIT cache entry {module_name} was not compiled within "
                    f"{timeout} s (a compilation that stopped, or one still running); delete "
                    f"{cache_dir / module_name}.* or the directory {cache_dir}") from None
            except (ImportError, OSError, AttributeError) as exc:
                why = f"{type(exc).__name__}: {exc}"
        discard_jit_entry(cache_dir, module_name)
        if cache_dir not in _JIT_REPAIRED:         # one line, however many entries
            _JIT_REPAIRED.add(cache_dir)
            print(warning_line(f"damaged FFCx JIT cache entry {cache_dir / module_name} "
                               f"({' '.join(why.split())}): compiling it again (and any other "
                               "damaged entry of this directory)"), file=sys.stderr)
        return get_cached_module(module_name, object_names, cache_dir, timeout)
    get_cached.vpcontact_repairing = True
    return get_cached


def one_line_jit_errors(ffcx_jit):
    """dolfinx's ``ffcx_jit`` whose JitCacheError reaches every rank as itself.

    Under mpirun dolfinx turns rank 0's exception into a RuntimeError on every rank (with
    "Compilation failed on root node." on the others); rank 0's JitCacheError is sent to
    all, so that the command line gives its one line.

    Args:
        ffcx_jit: dolfinx.jit.ffcx_jit (the MPI-decorated function).

    Returns:
        The replacement, same signature and results.
    """
    @functools.wraps(ffcx_jit)
    def jit(comm, *args, **kwargs):
        global _JIT_DAMAGED
        _JIT_DAMAGED = None
        try:
            return ffcx_jit(comm, *args, **kwargs)
        except RuntimeError:
            if comm.size == 1:
                raise
            damaged = comm.bcast(str(_JIT_DAMAGED) if _JIT_DAMAGED else None, root=0)
            if damaged is None:
                raise
            raise JitCacheError(damaged) from None
    jit.vpcontact_repairing = True
    return jit



def environmental(compile_objects):
    """An FFCx ``compile_*`` function whose environmental faults (an OSError: disk full,
    read-only; cffi's VerificationError: the C compiler failed, e.g. for want of space)
    are a JitCacheError naming the cache directory.

    Args:
        compile_objects: e.g. ffcx.codegeneration.jit.compile_forms.

    Returns:
        The replacement, same signature and results.
    """
    @functools.wraps(compile_objects)
    def compile_(*args, **kwargs):
        try:
            return compile_objects(*args, **kwargs)
        except JitCacheError:
            raise
        except Exception as exc:
            import cffi
            if not isinstance(exc, (OSError, cffi.VerificationError)):
                raise
            why = exc.strerror if isinstance(exc, OSError) and exc.strerror else \
                " ".join(str(exc).split())
            raise _damaged(f"compiling a form into the FFCx JIT cache {kwargs.get('cache_dir')} "
                           f"failed ({why}); free space there, check that the C compiler "
                           "works, or set XDG_CACHE_HOME to another directory") from exc
    compile_.vpcontact_repairing = True
    return compile_


JIT_COMPILERS = ("compile_forms", "compile_elements", "compile_expressions",
                 "compile_coordinate_maps")


def _patch_jit(dolfinx_jit) -> None:
    """Put ``repairing``, ``environmental`` and ``one_line_jit_errors`` in place (once) in
    the modules that dolfinx calls at every compilation."""
    ffcx_jit_module = sys.modules["ffcx.codegeneration.jit"]
    if not getattr(ffcx_jit_module.get_cached_module, "vpcontact_repairing", False):
        ffcx_jit_module.get_cached_module = repairing(ffcx_jit_module.get_cached_module)
    for name in JIT_COMPILERS:
        fn = getattr(ffcx_jit_module, name, None)
        if fn is not None and not getattr(fn, "vpcontact_repairing", False):
            setattr(ffcx_jit_module, name, environmental(fn))
    if not getattr(dolfinx_jit.ffcx_jit, "vpcontact_repairing", False):
        dolfinx_jit.ffcx_jit = one_line_jit_errors(dolfinx_jit.ffcx_jit)


class _AfterImport(importlib.abc.MetaPathFinder):
    """Runs ``then(module)`` right after the module ``name`` is first imported."""

    def __init__(self, name: str, then):
        self.name, self.then = name, then

    def find_spec(self, fullname, path, target=None):
        """The spec the other finders give, its loader's exec_module followed by ``then``.

        Args:
            fullname: the module being imported.
            path: the parent package's __path__.
            target: as for importlib's finders.

        Returns:
            The spec, or None for every other module.
        """
        if fullname != self.name:
            return None
        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        if spec is None or not hasattr(spec.loader, "exec_module"):
            return None
        exec_module = spec.loader.exec_module

        def exec_then(module):
            exec_module(module)
            self.then(module)
        spec.loader.exec_module = exec_then
        return spec


def install_jit_repair() -> None:
    """Make dolfinx's JIT compile damaged cache entries again (``repairing``): at once if
    dolfinx.jit is imported, else when it is."""
    if "dolfinx.jit" in sys.modules:
        _patch_jit(sys.modules["dolfinx.jit"])
    elif not any(isinstance(f, _AfterImport) for f in sys.meta_path):
        sys.meta_path.insert(0, _AfterImport("dolfinx.jit", _patch_jit))
