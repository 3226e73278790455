"""Building the C kernels with cffi, cached like dolfinx's JIT forms.

Each compiled library (``Library``) is made of C files of this package: its ``.c`` files,
compiled as one translation unit in the given order, and their ``.h`` files, whose
prototypes are cffi's cdef (preprocessor lines and comments stripped).  The build goes to
the ``kernels`` directory of the cache (app/cachepaths.py) under a name keyed by a hash of
everything it depends on: the contents of every ``.c``/``.h`` used, the compiler flags, the
libraries and include directories, and the Python version.  Concurrent builds (mpirun ranks)
write to private directories and publish the library by an atomic rename; a cached library
that does not load is rebuilt; where nothing can be built (no compiler, no library) ``load``
returns None with a warning and the callers use their numpy reference instead.
"""
from __future__ import annotations

import hashlib
import importlib.util
import logging
import os
import re
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

log = logging.getLogger("vpcontact")

HERE = Path(__file__).resolve().parent
_MODULES: dict[object, object] = {}       # by name, and by Library (Library.load)
# no errno from sqrt and no FP traps assumed: lets the cell loops be if-converted and
# vectorised; the results are IEEE's either way (no -ffast-math; c99: no FMA contraction)
CFLAGS = ["-O3", "-std=c99", "-fno-math-errno", "-fno-trapping-math"]


def cache_dir() -> Path:
    """Where the compiled kernels are kept.

    Returns:
        The ``kernels`` directory of the cache (app/cachepaths.py).
    """
    from vpcontact.cachepaths import caches
    return caches().kernels


_CTYPES = {np.dtype(np.float64): "double[]", np.dtype(np.float32): "float[]",
           np.dtype(np.intc): "int[]"}


def buf(ffi, a: np.ndarray | None):
    """A C array argument for a kernel.

    Args:
        ffi: the compiled module's ``ffi``.
        a: a contiguous float64, float32 or intc array (kept alive by the result), or None.

    Returns:
        A C array of doubles or ints viewing ``a``; NULL for None.

    Raises:
        TypeError: for another dtype (cffi refuses non-contiguous arrays).
    """
    if a is None:
        return ffi.NULL
    if a.dtype not in _CTYPES:
        raise TypeError(f"kernel arrays must be float64, float32 or intc, not {a.dtype}")
    return ffi.from_buffer(_CTYPES[a.dtype], a)        # refuses non-contiguous arrays


def read_cdef(header: str) -> str:
    """The declarations of a C header as cffi's cdef.

    Args:
        header: the text of a ``.h`` file (prototypes, include guards, comments).

    Returns:
        The text without comments and preprocessor lines, blank lines dropped.
    """
    text = re.sub(r"/\*.*?\*/", " ", header, flags=re.S)
    text = re.sub(r"//[^\n]*", "", text)
    lines = [ln.rstrip() for ln in text.splitlines()]
    return "\n".join(ln for ln in lines if ln.strip() and not ln.lstrip().startswith("#"))


def module_name(prefix: str, *texts: str, **kwargs) -> str:
    """The cache entry's name of a build.

    Args:
        prefix: the module's name without the hash.
        texts: every text the build reads (cdef, sources, headers).
        kwargs: the build's options (libraries, include directories).

    Returns:
        ``prefix`` and a hash of the texts, the options, CFLAGS and the Python version.
    """
    digest = hashlib.sha256()
    for text in (*texts, repr(sorted(kwargs.items())), repr(CFLAGS), sys.version):
        digest.update(text.encode())
        digest.update(b"\0")
    return f"{prefix}_{digest.hexdigest()[:16]}"


def _build(name: str, target: Path, cdef: str, source: str, **kwargs) -> None:
    """Compile into a private temporary directory next to ``target``, then publish the
    library by an atomic rename: concurrent builds (mpirun ranks, other runs) and builds
    killed half-way never leave a partial ``target``."""
    import cffi
    ffi = cffi.FFI()
    ffi.cdef(cdef)
    ffi.set_source(name, source, extra_compile_args=CFLAGS, **kwargs)
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target.parent, prefix=f".{name}-") as tmp:
        built = Path(ffi.compile(tmpdir=tmp, verbose=False))
        os.replace(built, target)


def _import(name: str, target: Path):
    spec = importlib.util.spec_from_file_location(name, target)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _load_or_build(name: str, target: Path, build, what: str):
    """The cached module; built first (``build(target)``) if missing, rebuilt if it does not
    load (a truncated or otherwise damaged file; a truncated one is found by its ELF
    headers before it is loaded: it would load and die with SIGBUS)."""
    from vpcontact.io.cachedirs import elf_damage
    if target.exists():
        try:
            why = elf_damage(target)
            if why is None:
                return _import(name, target)
        except Exception as exc:                        # noqa: BLE001 (any damage)
            why = exc
        log.info("the cached library %s does not load (%s): rebuilding it", target, why)
    else:
        log.info("compiling %s into %s", what, target.parent)
    build(target)
    return _import(name, target)


def _cached(name: str, build, what: str):
    """The module ``name`` of this process, the cache or a new build; None (and a warning
    naming ``what``) if it cannot be built here."""
    if name in _MODULES:
        return _MODULES[name]
    target = cache_dir() / f"{name}.so"
    try:
        module = _load_or_build(name, target, build, what)
    except Exception as exc:                            # no compiler (or library): fallback
        log.warning("%s unavailable (%s)", what, exc)
        module = None
    _MODULES[name] = module
    return module


def compiled(prefix: str, cdef: str, source: str, what: str, **kwargs):
    """A cffi module from C text (for small generated modules and the tests; the kernels
    of this package are built from their files by ``Library``).

    Args:
        prefix: the module's name without the hash.
        cdef: the declarations cffi exposes.
        source: the C source.
        what: names the module in the log (and in the warning if it cannot be built).
        kwargs: options of cffi's ``set_source`` (libraries, include_dirs).

    Returns:
        The module (``.lib``, ``.ffi``), or None if it cannot be built here.
    """
    name = module_name(prefix, cdef, source, **kwargs)
    return _cached(name, lambda target: _build(name, target, cdef, source, **kwargs), what)


@dataclass(frozen=True)
class Library:
    """A compiled library of this package's C files.

    Attributes:
        prefix: the module's name without the hash (``_vpcontact_...``).
        parts: the stems of its ``.c``/``.h`` pairs, compiled in this order.
        what: names it in the log; the warning says what is used instead.
        libraries: the libraries it is linked to.
        include_dirs: extra include directories (the package's own is always searched).
    """

    prefix: str
    parts: tuple[str, ...]
    what: str
    libraries: tuple[str, ...] = ()
    include_dirs: tuple[str, ...] = ()

    def headers(self) -> list[Path]:
        """The headers.

        Returns:
            The ``.h`` files, in order (their prototypes are the cdef).
        """
        return [HERE / f"{part}.h" for part in self.parts]

    def sources(self) -> list[Path]:
        """The sources.

        Returns:
            The ``.c`` files, in the order they are compiled.
        """
        return [HERE / f"{part}.c" for part in self.parts]

    def cdef(self) -> str:
        """The declarations cffi exposes.

        Returns:
            The cdef read from the headers (``read_cdef``).
        """
        return "\n".join(read_cdef(h.read_text()) for h in self.headers())

    def _options(self) -> dict:
        return dict(libraries=list(self.libraries), include_dirs=list(self.include_dirs))

    def name(self) -> str:
        """The cache entry's name.

        Returns:
            The prefix and a hash of the contents of every file used, the options, the flags
            and the Python version (not of the package's location).
        """
        texts = [f"{p.name}\n{p.read_text()}" for p in (*self.headers(), *self.sources())]
        return module_name(self.prefix, *texts, **self._options())

    def library_file(self) -> Path:
        """The cache file of the compiled library (``load`` builds it).

        Returns:
            Its path in cache_dir().
        """
        return cache_dir() / f"{self.name()}.so"

    def _build(self, name: str, target: Path) -> None:
        source = "".join(p.read_text() for p in self.sources())
        options = self._options()
        options["include_dirs"] = [str(HERE), *options["include_dirs"]]
        _build(name, target, self.cdef(), source, **options)

    def load(self):
        """The compiled library (``.lib``, ``.ffi``), built into cache_dir() if it is not
        there yet; found once per process (``name`` reads and hashes every file, and some
        callers load per step; docs/performance.md, section 9).

        Returns:
            The cffi module, or None if it cannot be built here (a warning says so).
        """
        if self not in _MODULES:
            name = self.name()
            _MODULES[self] = _cached(name, lambda target: self._build(name, target), self.what)
        return _MODULES[self]
