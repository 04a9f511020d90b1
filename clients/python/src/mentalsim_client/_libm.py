"""The C math library's functions, for the arithmetic the Rust runtime does.

Rust's ``f32::exp``, ``tanh``, ``ln``, ``ln_1p``, ``sin``, ``cos`` and ``f64::atan2``, ``sin``,
``cos``, ``hypot`` call the platform's C math library (glibc's ``expf``, ``tanhf``, ... on
Linux), whose results are not always correctly rounded. Calling the same functions here gives
the same bits as ``learning::Policy`` on the same machine. Where no C math library can be
loaded, the functions are computed in double precision and rounded (``EXACT`` is false): equal
to the C library's but for rare last-bit differences.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import math
import sys
from collections.abc import Callable
from typing import Any, Final

import numpy as np
import numpy.typing as npt

F32Array = npt.NDArray[np.float32]


def _load() -> ctypes.CDLL | None:
    names = [ctypes.util.find_library("m"), "libm.so.6"]
    if sys.platform == "darwin":
        names.append("/usr/lib/libSystem.B.dylib")
    for name in names:
        if not name:
            continue
        try:
            return ctypes.CDLL(name)
        except OSError:
            continue
    return None


_LIB: Final = _load()


def _symbol(name: str) -> Any:
    """The C library's function `name`, or None (no library, or no such function)."""
    if _LIB is None:
        return None
    return getattr(_LIB, name, None)


def _f32(name: str, fallback: Callable[[float], float]) -> Callable[[float], float]:
    fn = _symbol(name)
    if fn is not None:
        fn.argtypes = [ctypes.c_float]
        fn.restype = ctypes.c_float
        c_fn: Callable[[float], float] = fn
        return c_fn

    def rounded(x: float) -> float:
        try:
            return float(np.float32(fallback(x)))
        except OverflowError:
            return math.inf

    return rounded


def _f64(name: str, fallback: Callable[..., float], arity: int) -> Callable[..., float]:
    fn = _symbol(name)
    if fn is not None:
        fn.argtypes = [ctypes.c_double] * arity
        fn.restype = ctypes.c_double
        c_fn: Callable[..., float] = fn
        return c_fn
    return fallback


def _exp(x: float) -> float:
    return math.exp(x) if x < 709.0 else math.inf


#: Whether the functions are the C math library's own.
EXACT: Final = _LIB is not None

expf: Final = _f32("expf", _exp)
tanhf: Final = _f32("tanhf", math.tanh)
logf: Final = _f32("logf", lambda x: math.log(x) if x > 0 else (-math.inf if x == 0 else math.nan))
log1pf: Final = _f32("log1pf", lambda x: math.log1p(x) if x > -1 else (-math.inf if x == -1 else math.nan))
sinf: Final = _f32("sinf", math.sin)
cosf: Final = _f32("cosf", math.cos)

atan2: Final = _f64("atan2", math.atan2, 2)
sin: Final = _f64("sin", math.sin, 1)
cos: Final = _f64("cos", math.cos, 1)
hypot: Final = _f64("hypot", math.hypot, 2)


def map_f32(fn: Callable[[float], float], values: F32Array) -> F32Array:
    """``fn`` applied to every element of a float32 array."""
    flat = values.astype(np.float32, copy=False).ravel()
    out = np.fromiter((fn(float(v)) for v in flat), dtype=np.float32, count=flat.size)
    return out.reshape(values.shape)
