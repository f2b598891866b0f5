"""How the kernel is compiled: once per piece, cached as a whole, and quickly the first time.

A function decorated with ``numba.njit`` is compiled on its own (with a Python wrapper and its
own machine code) and then compiled *again* inside every jitted caller, whose module links and
re-optimises it. For the large sections of the kernel that multiplies the one-time compile.

- ``compiled``: the kernels' ``njit`` (no ``fastmath``, NumPy's error model, the GIL released),
  cached on disk under a stamp of *every* kernel module (:data:`KERNEL_MODULES`): Numba's own
  stamp covers the file that defines a function only, while an entry embeds code from several
  files, so a change in one of them would otherwise leave a stale entry in the cache.
- ``subroutine``: a helper of the kernels (their sections, the geometry, the fast maths) is
  typed, lowered and optimised once per process and argument types, then linked into each
  jitted caller that uses it (Numba's own mechanism for internal helpers, as
  ``BaseContext.compile_subroutine``), and cached with the entry. Its library is optimised but
  never turned into machine code of its own (:class:`_UnemittedLibrary`): nothing calls it there,
  and an ``njit`` helper also gets a Python wrapper for every signature. From Python (tests) it
  runs as an ``njit`` function compiled on first use. (A library that only links the
  subroutine's code, never optimising it on its own, saved about 2 s of the first compilation of
  each large entry but made the warm Algorithm 1 13-49 % slower: LLVM's second pass over the
  optimised subroutine finds more; not kept, ``benchmarks/JOURNAL.md``, "First run".)
- ``entry_call``: an ``njit`` entry that Python and several jitted callers all call is called
  from the jitted ones through its address, found at run time in a table of its compiled code
  (``entry_table``), so that no caller links or re-optimises it.

Measured on the first compilation (``benchmarks/README.md``, "First run"): code that allocates
an array, assigns a slice or calls ``np.argmax`` inside a kernel makes Numba compile its
error-message formatting (about 3 s per process); the kernels take their buffers from the
caller and loop instead.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import os
from typing import Any, Callable

from numba import njit
from numba.core import compiler, config, types
from numba.core.caching import CompileResultCacheImpl, FunctionCache
from numba.core.codegen import JITCodeLibrary
from numba.core.compiler_lock import global_compiler_lock
from numba.core.extending import _Intrinsic
from numba.extending import intrinsic

KERNEL_MODULES = ("jit", "fastmath", "layout", "geometry", "uav_kernel", "team_kernel", "search_kernels", "kernels")
"""The modules of ``staghunt.engine`` whose code ends up in the compiled entries: a change in any
of them makes every cached entry stale (:func:`kernel_stamp`)."""


def kernel_stamp() -> bytes:
    """SHA-256 over the sources of :data:`KERNEL_MODULES` (read once per process and change)."""
    here = os.path.dirname(os.path.abspath(__file__))
    files = [os.path.join(here, f"{name}.py") for name in KERNEL_MODULES]
    return _stamp(tuple((f, os.stat(f).st_mtime_ns, os.stat(f).st_size) for f in files))


@functools.lru_cache(maxsize=8)
def _stamp(files: tuple[tuple[str, int, int], ...]) -> bytes:
    digest = hashlib.sha256()
    for path, _, _ in files:
        with open(path, "rb") as f:
            digest.update(f.read())
    return digest.digest()


class _KernelStamp:
    """A cache locator's mixin: the source stamp is :func:`kernel_stamp`."""

    def get_source_stamp(self) -> bytes:
        return kernel_stamp()


class _KernelCacheImpl(CompileResultCacheImpl):
    _locator_classes = [type(f"Kernel{c.__name__}", (_KernelStamp, c), {})
                        for c in CompileResultCacheImpl._locator_classes]


class _KernelCache(FunctionCache):
    """Numba's on-disk cache of a function (same places, ``NUMBA_CACHE_DIR`` rules), stamped by
    :func:`kernel_stamp`."""

    _impl_class = _KernelCacheImpl


def compiled(parallel: bool = False) -> Callable[[Callable[..., Any]], Any]:
    """``njit`` for the kernels (``nogil``, NumPy's error model, no ``fastmath``; ``parallel``
    for a ``prange`` loop), cached on disk with :class:`_KernelCache`. With
    ``NUMBA_DISABLE_JIT=1`` the plain function is returned."""

    def wrap(fn: Callable[..., Any]) -> Any:
        dispatcher = njit(nogil=True, error_model="numpy", parallel=parallel)(fn)
        if not config.DISABLE_JIT:
            dispatcher._cache = _KernelCache(dispatcher.py_func)
        return dispatcher

    return wrap


def subroutine(fn: Callable[..., Any]) -> Any:
    """Wrap a plain Python function as a subroutine of the compiled kernels (IEEE semantics,
    NumPy error model: no exception on division by zero, no ``fastmath``): a jitted caller
    types, lowers and optimises it once per process and argument types, and links its optimised
    code into its own (:class:`_UnemittedLibrary`: no machine code or Python wrapper of its own,
    which a function decorated with ``njit`` gets for every signature a caller uses). Called from
    Python (tests), it runs as an ``njit`` function compiled on first use. With
    ``NUMBA_DISABLE_JIT=1`` the plain function is returned (debugging in Python)."""
    if config.DISABLE_JIT:
        return fn
    from numba.core.registry import cpu_target

    def typer(typingctx: Any, *args: Any) -> Any:
        argtys = tuple(types.unliteral(a) for a in args)
        cres = _compile_subroutine(cpu_target.target_context, fn, argtys)
        signature = cres.signature.return_type(*argtys)

        def codegen(context: Any, builder: Any, sig: Any, llargs: Any) -> Any:
            linked = _compile_subroutine(context, fn, argtys)  # the typer's, from the context's cache
            context.active_code_library.add_linking_library(linked.library)
            values = [context.cast(builder, v, t, u) for v, t, u in zip(llargs, sig.args, argtys)]
            return context.call_internal(builder, linked.fndesc, signature, values)

        return signature, codegen

    params = ", ".join(inspect.signature(fn).parameters)
    namespace: dict[str, Any] = {"typer": typer}
    exec(f"def {fn.__name__}(typingctx, {params}):\n    return typer(typingctx, {params})\n", namespace)
    wrapped = namespace[fn.__name__]
    wrapped.__doc__ = fn.__doc__
    wrapped.__module__ = fn.__module__
    sub = _Subroutine(fn.__name__, wrapped)
    sub._register()
    sub.py_func = fn
    sub.__doc__ = fn.__doc__
    return sub


class _Subroutine(_Intrinsic):
    """A :func:`subroutine`: an intrinsic to jitted callers, an ``njit`` function (compiled on
    first use) to Python."""

    py_func: Callable[..., Any] | None = None
    _python: Any = None

    def __call__(self, *args: Any) -> Any:
        if self._python is None:
            self._python = njit(error_model="numpy")(self.py_func)
        return self._python(*args)


class _UnemittedLibrary(JITCodeLibrary):
    """A subroutine's code library: optimised (its callers link the optimised module), but never
    turned into machine code of its own, which nothing calls: the caller's module holds the code
    that runs."""

    def _finalize_final_module(self) -> None:
        self._finalize_dynamic_globals()
        self._verify_declare_only_symbols()
        self._finalized = True


def _compile_subroutine(context: Any, fn: Callable[..., Any], argtys: tuple[Any, ...]) -> Any:
    """Compile ``fn`` for ``argtys`` into an :class:`_UnemittedLibrary`, once per target context
    (its ``cached_internal_func``, as ``context.compile_subroutine`` does)."""
    key = (fn.__code__, argtys, _UnemittedLibrary)
    cres = context.cached_internal_func.get(key)
    if cres is None:
        with global_compiler_lock:
            flags = compiler.Flags()
            flags.error_model = "numpy"
            flags.nrt = True
            flags.no_compile = True
            flags.no_cpython_wrapper = True
            flags.no_cfunc_wrapper = True
            library = _UnemittedLibrary(context.codegen(), fn.__name__)
            cres = compiler.compile_internal(context.typing_context, context, library, fn, argtys, None, flags,
                                             locals={})
        context.cached_internal_func[key] = cres
    return cres


def entry_call(dispatcher: Any) -> Any:
    """An intrinsic ``call(entries, probe, *args)`` that runs ``dispatcher``'s compiled code for
    ``args`` through its address, looked up at run time in ``entries`` (:func:`entry_table`);
    with ``probe`` true it only looks the address up.

    A caller that calls an ``njit`` function directly links that function's code into its own
    module and optimises it again there; for the two large kernel entries that tripled the
    one-time compile of the callers. Through its address, the callee is compiled (and cached)
    once, on its own, and every caller is compiled without it; the call itself costs what a
    direct call does (measured: see ``benchmarks/README.md``). The caller is compiled without
    the callee (so the two may compile at once, in two processes): it keeps the fingerprint of
    the call's argument types (literals made plain) and, at run time, raises ``RuntimeError``
    if ``entries`` has no code for them (a parallel loop does not pass an exception on reliably:
    probe once before it); whoever runs the caller has compiled or loaded the callee for those
    types (:func:`staghunt.engine.compilation.prepare`). The address is
    an argument, never a constant, so a cached caller stays valid in a new process. With
    ``NUMBA_DISABLE_JIT=1`` the plain function is called."""
    if config.DISABLE_JIT:
        return lambda entries, probe, *args: None if probe else dispatcher(*args)
    from llvmlite import ir
    from numba.core import cgutils

    def find(entries: Any, fingerprint: int) -> int:
        for i in range(entries.shape[0]):
            if entries[i, 0] == fingerprint:
                return entries[i, 1]
        return 0

    def typer(typingctx: Any, entries: Any, probe: Any, *args: Any) -> Any:  # noqa: ARG001
        argtys = tuple(types.unliteral(a) for a in args)
        fingerprint = signature_fingerprint(argtys)
        message = f"staghunt.engine: no compiled {dispatcher.__name__} for the caller's argument types"

        def codegen(context: Any, builder: Any, signature: Any, llargs: Any) -> Any:
            table, values = llargs[0], llargs[2:]
            only_probe = context.cast(builder, llargs[1], signature.args[1], types.boolean)
            values = [context.cast(builder, v, t, u) for v, t, u in zip(values, signature.args[2:], argtys)]
            i64 = ir.IntType(64)
            address = context.compile_internal(builder, find, types.int64(entries, types.int64),
                                               [table, ir.Constant(i64, fingerprint)])
            with builder.if_then(builder.icmp_unsigned("==", address, ir.Constant(i64, 0)), likely=False):
                context.call_conv.return_user_exc(builder, RuntimeError, (message,))
            with builder.if_then(builder.not_(only_probe), likely=True):
                fnty = context.call_conv.get_function_type(types.none, argtys)
                status, _ = context.call_conv.call_function(builder, builder.inttoptr(address, fnty.as_pointer()),
                                                            types.none, argtys, values)
                with cgutils.if_unlikely(builder, status.is_error):
                    context.call_conv.return_status_propagate(builder, status)
            return context.get_dummy_value()

        return types.none(entries, probe, *args), codegen

    names = ", ".join(inspect.signature(dispatcher.py_func).parameters)
    namespace: dict[str, Any] = {"typer": typer}
    exec(f"def {dispatcher.__name__}_by_address(typingctx, entries, probe, {names}):\n"
         f"    return typer(typingctx, entries, probe, {names})\n", namespace)
    return intrinsic(namespace[f"{dispatcher.__name__}_by_address"])


def signature_fingerprint(argtys: tuple[Any, ...]) -> int:
    """A fingerprint of a tuple of Numba types, the same in every process (CRC-32 of its text)."""
    import zlib

    return zlib.crc32(str(tuple(argtys)).encode())


_TABLES: dict[int, tuple[int, Any]] = {}


def entry_table(dispatcher: Any) -> Any:
    """``(M, 2)`` int64: ``(signature fingerprint, address)`` of each of ``dispatcher``'s compiled
    overloads returning ``None`` (what :func:`entry_call` calls), remade when it gains one."""
    import numpy as np

    overloads = getattr(dispatcher, "overloads", {})
    known = _TABLES.get(id(dispatcher))
    if known is None or known[0] != len(overloads):
        rows = [(signature_fingerprint(sig), cres.library.get_pointer_to_function(cres.fndesc.llvm_func_name))
                for sig, cres in list(overloads.items()) if cres.signature.return_type == types.none]
        table = np.array(rows, dtype=np.int64).reshape(-1, 2)
        known = _TABLES[id(dispatcher)] = (len(overloads), table)
    return known[1]
