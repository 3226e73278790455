"""The caches at the command line's start and the FFCx JIT cache's damaged entries.

``start`` prepares the cache directories (app/cachepaths.py: where they are, and a usable
replacement for one that is not writable) when the command line starts, before dolfinx,
and prints the one warning line naming what was replaced; the rest of this module finds and
discards damaged entries of dolfinx's FFCx JIT cache (see below).
"""
from __future__ import annotations

import functools
import importlib.abc
import importlib.machinery
import os
import shutil
import struct
import sys
import time
from pathlib import Path

from vpcontact.cachepaths import Caches, CacheUnusable, prepare_caches
from vpcontact.io.messages import EXIT_FAILED, error, warning, warning_line


def warning_text(caches: Caches) -> str | None:
    """The warning lines of the caches replaced, as printed.

    Args:
        caches: the directories in use (app/cachepaths.py: ``prepare``).

    Returns:
        The lines of ``Caches.warnings``, joined by newlines; None if there is nothing to say.
    """
    return "\n".join(warning_line(m) for m in caches.warnings()) or None


def start(rank: int) -> None:
    """At import of the package: prepare the caches; rank 0 prints the warning, if any.

    With no writable directory at all, the one-line error and exit code 1 (an environmental
    fault, like a full disk).

    Args:
        rank: this process's MPI rank.

    Raises:
        SystemExit: (1) if no writable directory could be found for a cache.
    """
    try:
        prepared = prepare_caches()
    except CacheUnusable as exc:
        raise SystemExit(error(str(exc), EXIT_FAILED, rank)) from None
    for message in prepared.warnings():
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
