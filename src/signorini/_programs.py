"""Compiled programs kept between processes.

A :class:`Program` is a ``jax.jit`` whose compiled executables are also kept on
disk, keyed by what determines them: the owner's content key (a model's
structure digest: mesh, definitions, parameter names; see
:mod:`signorini.model.identity`), the program's name, the shapes and types of
its arguments, the code of this package, the JAX and jaxlib versions and the
CPU. A second process with the same key loads the executable (a few
milliseconds) instead of tracing, lowering and compiling it again (or loading
it from JAX's own compilation cache, which still needs the tracing and
lowering to find it).

Where: ``$SIGNORINI_CACHE_DIR/programs`` if that variable is set (an empty value
switches every cache off), else ``$XDG_CACHE_HOME/signorini/programs`` (default
``~/.cache/signorini/programs``); ``signorini cache --clear`` empties it, as
does deleting the directory. Its size is capped (``$SIGNORINI_CACHE_MAX_MB``,
default 2048): past the cap the entries used least recently are deleted. A
program larger than a quarter of the cap is not kept (a huge mesh, whose
compilation is a small part of its run anyway). Every entry carries a checksum
of its contents and a header naming its key: an entry that does not verify
(truncated, corrupted, written by other code) is compiled again and
overwritten, never used. Entries
are written to a temporary file and renamed into place, so processes that fill
the cache at once (a sweep's workers) neither see half-written entries nor
wait on a lock: the last one to finish a program keeps its copy.

A cache of executables is code that runs. An entry is loaded only if it is a
file of the user running the process that nobody else can write; the cache
directory (and its ``programs/`` and ``jax/``) only if the same holds for it,
else nothing is loaded from it nor kept in it. JAX's compilation cache in
``jax/`` gets the same checks, entry by entry (:func:`guard_jax_cache`), and
its damaged entries are deleted so that JAX writes them again. Every such
finding (a damaged entry, one that is not the user's own, a directory others
can write) is one :class:`~signorini.errors.SignoriniWarning` per cache
directory and process, naming the directory and what was done, and is listed
in :data:`WARNINGS` (so in summary.json); the run compiles what it could not
load, and its results are unaffected.
"""

from __future__ import annotations

import contextlib
import errno
import functools
import hashlib
import logging
import os
import stat
import pickle
import platform
import tempfile
import time
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

from ._jax import cache_dir, cache_path_problem, cache_root, jax, make_private_dir
from .errors import SignoriniWarning
from jax.core import Tracer

log = logging.getLogger("signorini")

#: layout of an entry on disk; a change makes every older entry a miss
FORMAT = 1
_MAGIC = b"signorini-program\n"
#: JAX monitoring event of the time spent loading an executable from disk
LOAD_EVENT = "/signorini/program_load"

#: per process: programs compiled here, loaded from disk, saved, rebuilt (a damaged
#: entry), ignored (an entry not the user's own), evicted; jax_rebuilt and
#: jax_ignored: the same for entries of JAX's compilation cache
STATS: Counter = Counter()
#: what was wrong with the cache's settings, directory or entries (each said once per process)
WARNINGS: list[str] = []


def warn_once(message: str, once: str | None = None) -> None:
    """A :class:`~signorini.errors.SignoriniWarning` about the cache, issued once
    per process and kept in :data:`WARNINGS` (every command's summary.json lists
    them), and an INFO line of the ``signorini`` log (which the command shows, as
    for every other warning): a cache that cannot be used makes runs slower,
    never wrong. ``once``: a beginning of the message; a message that begins so
    was said already (the first of several findings of one kind)."""
    if message in WARNINGS or (once is not None and any(w.startswith(once) for w in WARNINGS)):
        return
    WARNINGS.append(message)
    log.info("warning: %s", message)
    warnings.warn(message, SignoriniWarning, stacklevel=3)


def programs_dir() -> Path | None:
    """The directory of the kept programs (None: caching switched off)."""
    d = cache_root()
    return None if d is None else Path(d) / "programs"


def _disabled() -> bool:
    return os.environ.get("SIGNORINI_PROGRAM_CACHE", "1") in ("0", "", "off", "no")


# ------------------------------------------------------------ trust
_CODE = "a cache of compiled programs is code that runs"


def directory_problem(d) -> str | None:
    """Why nothing may be loaded from the cache directory ``d`` (None: it may;
    also when it does not exist yet, or is no directory: then nothing is found)."""
    try:
        st = os.stat(d)
    except OSError:
        return None
    return cache_path_problem(st) if stat.S_ISDIR(st.st_mode) else None


def _trusted_dirs(*dirs) -> bool:
    """Whether every one of ``dirs`` may be loaded from; warns (once per directory)
    about each one that may not."""
    ok = True
    for d in dirs:
        why = directory_problem(d)
        if why is None:
            continue
        ok = False
        fix = (f"make it private (chmod go-w {d})" if why.startswith("writable") else
               "set SIGNORINI_CACHE_DIR to a directory of your own")
        warn_once(f"the compilation cache {d} is {why}; {_CODE}, so nothing is loaded from it or "
                  f"kept in it (every run compiles again): {fix}, or switch the caches off with "
                  "SIGNORINI_CACHE_DIR= (empty)", once=f"the compilation cache {d} is ")
    return ok


def _entry_problem(st: os.stat_result) -> str | None:
    """Why a cache entry with this (l)stat must not be loaded (None: it may)."""
    if stat.S_ISLNK(st.st_mode):
        return "symbolic links"
    if not stat.S_ISREG(st.st_mode):
        return "not regular files"
    return cache_path_problem(st)


def _untrusted_entry(path: Path, why: str, what: str) -> None:
    log.debug("%s %s is %s: not loaded, compiled again", what, path, why)
    warn_once(f"the compilation cache {path.parent} holds entries that are {why} (the first: "
              f"{path.name}); {_CODE}, so they were ignored (not loaded), compiled again and "
              "replaced by entries of your own; if others can write to the cache, set "
              "SIGNORINI_CACHE_DIR to a directory of your own",
              once=f"the compilation cache {path.parent} holds entries")


def _damaged_entry(path: Path, reason, what: str) -> None:
    reason = " ".join(str(reason).split())
    reason = reason if len(reason) <= 160 else reason[:157] + "..."
    log.debug("%s %s is unusable (%s): compiled again", what, path, reason)
    warn_once(f"the compilation cache {path.parent} had damaged entries (the first: {path.name}: "
              f"{reason}); they were ignored, compiled again and replaced, and the results are "
              "unaffected (signorini cache --clear empties the cache)",
              once=f"the compilation cache {path.parent} had damaged entries")


@functools.cache
def code_version() -> str:
    """Digest of this package's source files: any change of the code is a new version."""
    root = Path(__file__).resolve().parent
    h = hashlib.blake2b(digest_size=16)
    for p in sorted(root.rglob("*.py")):
        h.update(str(p.relative_to(root)).encode())
        h.update(p.read_bytes())
    return h.hexdigest()


@functools.cache
def _platform() -> str:
    """JAX, jaxlib and the CPU the executables were compiled for."""
    flags = ""
    try:
        with open("/proc/cpuinfo") as f:
            flags = next((line for line in f if line.startswith("flags")), "")
    except OSError:
        pass
    import jaxlib  # noqa: PLC0415  (lazy: its version only)

    parts = (jax.__version__, jaxlib.__version__, platform.machine(), platform.processor(),
             hashlib.blake2b(flags.encode(), digest_size=8).hexdigest(),
             str(jax.config.jax_enable_x64))
    return "|".join(parts)


#: compile option of the kept programs: ignored by the CPU compiler, but part of the
#: key of JAX's compilation cache, which therefore never serves them
_OWN_KEY = {"xla_gpu_deterministic_ops": False}
_JAX_CACHE_HITS = [0]
_LISTENING = []


def _count_hits(event: str, **_) -> None:
    if event == "/jax/compilation_cache/cache_hits":
        _JAX_CACHE_HITS[0] += 1


def _no_jax_cache_writes():
    """A context in which JAX's compilation cache takes no new entries (this
    thread), or a no-op where this JAX does not offer it."""
    if not _LISTENING:
        _LISTENING.append(True)
        jax.monitoring.register_event_listener(_count_hits)
    try:
        from jax._src import config as jax_config  # noqa: PLC0415  (lazy: on a compile only)

        return jax_config.persistent_cache_min_compile_time_secs(float("inf"))
    except (ImportError, AttributeError, TypeError):
        return contextlib.nullcontext()


def _aval(x):
    """What a compiled program needs to know of an argument (None: not cacheable)."""
    if isinstance(x, Tracer):  # inside another program: traced with it
        return None
    if isinstance(x, jax.Array):
        return (x.shape, x.dtype.str, bool(getattr(x, "weak_type", False)))
    if isinstance(x, np.ndarray):
        return (x.shape, x.dtype.str, False)
    if isinstance(x, (bool, int, float, complex)):
        return ((), type(x).__name__, True)
    if isinstance(x, np.generic):
        return ((), x.dtype.str, False)
    return None


class Program:
    """``jax.jit(fn)`` whose executables are kept in memory and, when ``key`` is
    given, on disk (module docstring).

    Args:
        fn: the function (pure; what it closes over must be fixed by ``key``).
        name: its name within the owner (part of the disk key).
        key: the owner's content digest (str), or None: memory only; or a function
            returning either, read when a program is built (an owner whose settings
            change what is traced keys them in at that time).
        static_argnums: as for ``jax.jit``.
    """

    def __init__(self, fn, name: str, key: str | None = None, static_argnums=()):
        self.jit = jax.jit(fn, static_argnums=static_argnums)
        self.name = name
        self.key = key
        self.static = tuple(static_argnums) if isinstance(static_argnums, (tuple, list)) \
            else (static_argnums,)
        self._compiled: dict = {}

    def lower(self, *args, **kwargs):
        return self.jit.lower(*args, **kwargs)

    def prepare(self, *args) -> None:
        """Build (compile or load) the executable for these arguments' types
        without running it: callers that then run it from several threads build
        it once, here."""
        dynamic = [a for k, a in enumerate(args) if k not in self.static]
        leaves, tree = jax.tree_util.tree_flatten(dynamic)
        avals = tuple(_aval(x) for x in leaves)
        sig = (tree, avals, tuple(args[k] for k in self.static))
        if None not in avals and sig not in self._compiled:
            self._compiled[sig] = self._build(args, sig)

    def __call__(self, *args):
        dynamic = [a for k, a in enumerate(args) if k not in self.static]
        leaves, tree = jax.tree_util.tree_flatten(dynamic)
        avals = tuple(_aval(x) for x in leaves)
        if None in avals:  # a tracer (called inside another program) or an odd argument
            return self.jit(*args)
        sig = (tree, avals, tuple(args[k] for k in self.static))
        c = self._compiled.get(sig)
        if c is None:
            c = self._compiled[sig] = self._build(args, sig)
        return c(*dynamic)

    # ------------------------------------------------------------ disk cache
    def _path(self, sig) -> Path | None:
        d = programs_dir()
        key = self._key()
        if key is None or d is None or _disabled():
            return None
        jax_dir = cache_dir()
        _trusted_dirs(*([] if jax_dir is None else [jax_dir]))  # said here: JAX's own cache is silent
        if not _trusted_dirs(d.parent, d):
            return None  # not loaded from, not kept: compiled in memory
        text = "\n".join((str(FORMAT), key, self.name, repr(sig), code_version(), _platform()))
        return d / (hashlib.blake2b(text.encode(), digest_size=20).hexdigest() + ".bin")

    def _build(self, args, sig):
        _BUILT[0] += 1
        if _BUILT[0] % CHECK_EVERY == 0:
            relieve()
        path = self._path(sig)
        if path is not None:
            c = self._load(path)
            if c is not None:
                return c
        t0 = time.perf_counter()
        if path is None:
            c = self.jit.lower(*args).compile()
            STATS["compiled"] += 1
            return c
        # An executable that JAX loaded from its own cache cannot be serialised again
        # (its object code is not carried along): a kept program is compiled by XLA
        # itself, under a key of its own in JAX's cache (an option the CPU compiler
        # ignores) that is never written there; one served from that cache all the
        # same is used but not kept
        hits = _JAX_CACHE_HITS[0]
        with _no_jax_cache_writes():
            c = self.jit.lower(*args).compile(compiler_options=_OWN_KEY)
        STATS["compiled"] += 1
        log.debug("program %s compiled in %.3f s", self.name, time.perf_counter() - t0)
        if _JAX_CACHE_HITS[0] == hits:
            self._save(path, c)
        return c

    def _key(self) -> str | None:
        return self.key() if callable(self.key) else self.key

    def _header(self) -> bytes:
        return f"{FORMAT}|{self.name}|{self._key()}|{code_version()}|{_platform()}\n".encode()

    def _load(self, path: Path):
        start = time.time()
        try:  # the checks and the read on one open file: what is checked is what is read
            fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
        except FileNotFoundError:
            return None  # not there (the usual miss)
        except OSError as e:
            if e.errno == errno.ELOOP:  # O_NOFOLLOW met a symbolic link
                STATS["ignored"] += 1
                _untrusted_entry(path, "symbolic links", f"kept program {self.name}")
            else:
                log.debug("kept program %s at %s cannot be read (%s)", self.name, path, e)
            return None
        with os.fdopen(fd, "rb") as f:
            why = _entry_problem(os.fstat(f.fileno()))
            if why is not None:
                STATS["ignored"] += 1
                _untrusted_entry(path, why, f"kept program {self.name}")
                return None
            try:
                blob = f.read()
            except OSError as e:
                log.debug("kept program %s at %s cannot be read (%s)", self.name, path, e)
                return None
        try:
            magic, header, digest, body = blob.split(b"\n", 3)
            if magic + b"\n" != _MAGIC or header + b"\n" != self._header():
                raise ValueError("written for another key, code or platform")
            if hashlib.blake2b(body, digest_size=32).hexdigest().encode() != digest:
                raise ValueError("checksum mismatch")
            from jax.experimental import serialize_executable  # noqa: PLC0415  (lazy: on a hit only)

            payload, in_tree, out_tree = pickle.loads(body)
            _lapack_ready()
            c = serialize_executable.deserialize_and_load(payload, in_tree, out_tree)
        except Exception as e:  # noqa: BLE001  (any bad entry is rebuilt, never used)
            STATS["rebuilt"] += 1
            _damaged_entry(path, e, f"kept program {self.name}")
            return None
        STATS["loaded"] += 1
        try:
            os.utime(path)  # used now: the last to be evicted
        except OSError:
            pass
        jax.monitoring.record_event_time_span(LOAD_EVENT, start, time.time())
        return c

    def _save(self, path: Path, compiled) -> None:
        try:
            from jax.experimental import serialize_executable  # noqa: PLC0415  (lazy: on a miss only)

            body = pickle.dumps(serialize_executable.serialize(compiled), protocol=5)
            if len(body) > max_bytes() // 4:
                log.debug("program %s (%.0f MB) is too large to keep", self.name, len(body) / 2**20)
                return
            digest = hashlib.blake2b(body, digest_size=32).hexdigest().encode()
            make_private_dir(path.parent.parent)
            make_private_dir(path.parent)
            fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=".bin")
            try:
                with os.fdopen(fd, "wb") as f:
                    f.write(_MAGIC + self._header() + digest + b"\n" + body)
                os.replace(tmp, path)  # atomic: readers see the old entry or the whole new one
            except BaseException:
                Path(tmp).unlink(missing_ok=True)
                raise
            STATS["saved"] += 1
            _evict(path.parent, keep=path)
        except OSError as e:  # a cache that cannot be written is only slower
            warn_once(f"compiled programs cannot be kept in {path.parent} ({e.strerror or e}): "
                      "every run compiles them again; set SIGNORINI_CACHE_DIR to a writable "
                      "directory (or to an empty value to switch the caches off)")
        except Exception as e:  # noqa: BLE001  (a cache that cannot be written is only slower)
            log.debug("could not keep program %s: %s", self.name, e)


@functools.cache
def _lapack_ready() -> None:
    """Register the CPU's LAPACK kernels before a kept program is loaded. JAX does
    so when it first lowers a linear-algebra operation; a program loaded from
    disk is not lowered, and one that calls LAPACK (a determinant, an inverse, a
    solve) then jumps to an unregistered kernel and the process dies
    (segmentation fault) if it is the first such program of the process. JAX's
    own loader of exported programs does the same (``_ensure_backends_initialized``)."""
    try:
        from jax._src.lax.linalg import initialize_lapack  # noqa: PLC0415  (lazy: private, on a load only)
        initialize_lapack()
    except Exception:  # noqa: BLE001  (another JAX: lower one such operation instead)
        jax.block_until_ready(jax.numpy.linalg.det(jax.numpy.eye(2)))


def code_maps() -> tuple[int, int] | None:
    """(memory mappings of this process, the most the system allows a process), or
    None where the system does not say (not Linux).

    Every executable in memory holds its machine code in mappings of its own, a
    few hundred for a 3-D contact model's larger programs; Linux allows a process
    ``vm.max_map_count`` of them (65,530 by default), and past it XLA's next
    executable dies in a segmentation fault, not an error. The models kept for
    reuse (:func:`signorini.algorithms.stepping.model_for`) are let go before that."""
    try:
        with open("/proc/sys/vm/max_map_count") as f:
            limit = int(f.read())
        with open("/proc/self/maps", "rb") as f:
            used = sum(1 for _ in f)
    except (OSError, ValueError):
        return None
    return used, limit


#: the share of the memory mappings the system allows a process (:func:`code_maps`)
#: past which the :data:`RELEASERS` let go of what they keep
MAP_SHARE = 0.5
#: executables built between two counts of the mappings (a count costs ~1 ms per 1,000)
CHECK_EVERY = 8
#: callables ``f(maps)`` that drop kept executables' owners (the models kept for reuse)
RELEASERS: list = []
_BUILT = [0]


def relieve() -> None:
    """Where the process holds more than :data:`MAP_SHARE` of the memory mappings
    it may (:func:`code_maps`), ask the :data:`RELEASERS` to let go of what they keep."""
    maps = code_maps()
    if maps is not None and maps[0] > MAP_SHARE * maps[1]:
        for release in RELEASERS:
            release(maps)


def max_bytes() -> int:
    """The cap of the kept programs' total size (``$SIGNORINI_CACHE_MAX_MB``, default 2048)."""
    text = os.environ.get("SIGNORINI_CACHE_MAX_MB", "2048")
    try:
        mb = float(text)
        if not mb >= 0 or mb == float("inf"):
            raise ValueError
    except ValueError:
        warn_once(f"SIGNORINI_CACHE_MAX_MB={text!r} is not a size in MB (a number >= 0); "
                  "using the default, 2048")
        mb = 2048.0
    return int(mb * 2**20)


def _evict(d: Path, keep: Path) -> None:
    """Delete the entries used least recently (a load touches its entry) until the
    directory is within :func:`max_bytes`; ``keep`` (just written) stays."""
    try:
        entries = []
        for e in os.scandir(d):
            if e.is_file() and e.name.endswith(".bin") and not e.name.startswith(".tmp-"):
                st = e.stat()
                entries.append((st.st_mtime, st.st_size, e.path))
    except OSError:
        return
    total, cap = sum(size for _, size, _ in entries), max_bytes()
    for _, size, p in sorted(entries):
        if total <= cap:
            break
        if p != str(keep):
            try:
                os.unlink(p)
                total -= size
                STATS["evicted"] += 1
            except OSError:
                pass


# ------------------------------------------------------------ JAX's compilation cache
#: how JAX names the file of a key in its cache directory (read from JAX when guarded)
_JAX_SUFFIX = "-cache"


def _jax_entry(cache_key: str) -> Path | None:
    """The file of a key in JAX's compilation cache (None: no cache directory)."""
    d = getattr(jax.config, "jax_compilation_cache_dir", None)
    return None if not d else Path(d) / f"{cache_key}{_JAX_SUFFIX}"


def _jax_dirs(entry: Path) -> tuple:
    """The directories whose trust an entry of JAX's cache depends on: its own and,
    when it is signorini's ``jax/``, the cache directory above it."""
    root = cache_root()
    up = (entry.parent.parent,) if root is not None and entry.parent.parent == Path(root) else ()
    return up + (entry.parent,)


def _discard(entry: Path) -> None:
    """Delete an entry of JAX's cache that was not used: JAX writes no entry over an
    existing one, so the program it compiles instead is kept only once it is gone."""
    try:
        entry.unlink()
    except FileNotFoundError:
        pass
    except OSError as e:
        log.debug("could not delete %s (%s): it stays unused", entry, e)


def _jax_get(get, should_raise):
    @functools.wraps(get)
    def guarded(cache_key, *args, **kwargs):
        entry = _jax_entry(cache_key)
        if entry is None:
            return get(cache_key, *args, **kwargs)
        if not _trusted_dirs(*_jax_dirs(entry)):
            return None, None  # nothing loaded from there: compiled
        try:
            st = os.lstat(entry)
        except OSError:
            return get(cache_key, *args, **kwargs)  # a miss (JAX finds nothing either)
        why = _entry_problem(st)
        if why is not None:
            STATS["jax_ignored"] += 1
            _untrusted_entry(entry, why, "JAX cache entry")
            _discard(entry)
            return None, None
        try:
            return get(cache_key, *args, **kwargs)
        except Exception as e:  # noqa: BLE001  (JAX would warn and compile; we say it once and rebuild)
            if should_raise(e):
                raise
            STATS["jax_rebuilt"] += 1
            _damaged_entry(entry, f"{type(e).__name__}: {e}", "JAX cache entry")
            _discard(entry)
            return None, None

    guarded._signorini_guard = True
    return guarded


def _jax_put(put, should_raise):
    @functools.wraps(put)
    def guarded(cache_key, *args, **kwargs):
        entry = _jax_entry(cache_key)
        if entry is not None and not _trusted_dirs(*_jax_dirs(entry)):
            return None  # nothing kept where it would not be loaded from
        try:
            put(cache_key, *args, **kwargs)
        except Exception as e:  # noqa: BLE001  (a cache that cannot be written is only slower)
            if should_raise(e):
                raise
            where = entry.parent if entry is not None else "JAX's compilation cache"
            reason = e.strerror if isinstance(e, OSError) and e.strerror else f"{type(e).__name__}: {e}"
            warn_once(f"compiled programs cannot be kept in {where} ({reason}): every run compiles "
                      "them again; set SIGNORINI_CACHE_DIR to a writable directory (or to an empty "
                      "value to switch the caches off)", once=f"compiled programs cannot be kept in {where}")
            return None
        if entry is not None:  # JAX writes with the umask's mode: the entry is made private
            with contextlib.suppress(OSError):
                if os.lstat(entry).st_uid == getattr(os, "getuid", lambda: -1)():
                    os.chmod(entry, 0o600)
        return None

    guarded._signorini_guard = True
    return guarded


def guard_jax_cache() -> bool:
    """Route JAX's persistent compilation cache through the checks of this module:
    an entry that is not the user's own (or that others can write) is not loaded,
    a damaged one is deleted and compiled again, each said as one
    :class:`~signorini.errors.SignoriniWarning` per directory (not JAX's own
    ``UserWarning`` on every run), and the entries JAX writes are made private.
    Idempotent; False where this JAX's internals differ (its own behaviour stays)."""
    global _JAX_SUFFIX
    try:  # optional: JAX's private cache modules; without them JAX's own handling stays
        from jax._src import compilation_cache as cc  # noqa: PLC0415  (optional: see above)
        from jax._src import compiler  # noqa: PLC0415  (optional: see above)
        from jax._src import lru_cache  # noqa: PLC0415  (optional: see above)

        get, put = cc.get_executable_and_time, cc.put_executable_and_time
        should_raise = compiler._should_raise_persistent_cache_error
        _JAX_SUFFIX = lru_cache._CACHE_SUFFIX
    except (ImportError, AttributeError) as e:
        log.debug("JAX's compilation cache is used unguarded (%s)", e)
        return False
    if not getattr(get, "_signorini_guard", False):
        cc.get_executable_and_time = _jax_get(get, should_raise)
    if not getattr(put, "_signorini_guard", False):
        cc.put_executable_and_time = _jax_put(put, should_raise)
    return True


guard_jax_cache()
