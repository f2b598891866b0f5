"""``subroutine``: compile a function straight into its caller's machine code.

A function decorated with ``numba.njit`` is compiled on its own (with a Python wrapper and its
own machine code) and then compiled *again* inside every jitted caller, whose module links and
re-optimises it. For the few large sections of the kernel that doubles the one-time compile.
A subroutine is typed and lowered only as part of its caller (through Numba's own mechanism for
internal helpers, ``BaseContext.compile_subroutine``), so its code is optimised and emitted
once, and it is cached with the caller (``cache=True`` on the caller). It cannot be called
from Python.
"""

from __future__ import annotations

import inspect
from typing import Any, Callable

from numba.core import compiler, config, types
from numba.extending import intrinsic


def subroutine(fn: Callable[..., None]) -> Any:
    """Wrap a plain Python function returning ``None`` as a jit-only subroutine (IEEE semantics,
    NumPy error model: no exception on division by zero, no ``fastmath``). With
    ``NUMBA_DISABLE_JIT=1`` the plain function is returned (debugging in Python)."""
    if config.DISABLE_JIT:
        return fn
    params = list(inspect.signature(fn).parameters)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        flags = compiler.Flags()
        flags.error_model = "numpy"
        flags.nrt = True
        flags.no_cpython_wrapper = True
        flags.no_cfunc_wrapper = True
        cres = context.compile_subroutine(builder, fn, signature, flags=flags)
        return context.call_internal(builder, cres.fndesc, signature, args)

    names = ", ".join(params)
    namespace: dict[str, Any] = {"types": types, "codegen": codegen}
    exec(f"def {fn.__name__}(typingctx, {names}):\n    return types.none({names}), codegen\n", namespace)
    typer = namespace[fn.__name__]
    typer.__doc__ = fn.__doc__
    typer.__module__ = fn.__module__
    return intrinsic(typer)
