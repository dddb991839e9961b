"""The twin's floating-point expressions, compiled so that every result is bit-identical.

CPython's ``math.hypot`` is not the C library's ``hypot``: since 3.8 it is CPython's own
``vector_norm`` (scaling, Dekker squaring, compensated sums, one correction of the root).
:func:`py_hypot` is that algorithm, operation for operation (CPython 3.11, no fma).
``x ** y`` on floats is the C library's ``pow`` after CPython's special cases; numba's
``**`` with a run-time exponent calls the same ``pow``, so :func:`py_pow` keeps the
exponent out of the compiler's sight (a constant 0.5 would become a square root).
The geometry functions mirror ``twin/geometry.py`` line for line.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from pnp_twin.twin.fast.jit import compiled

T27 = 134217729.0  # Veltkamp constant 2**27 + 1


@compiled(inline=True)
def py_hypot(a: float, b: float) -> float:
    """``math.hypot(a, b)`` exactly as CPython 3.11 computes it (finite inputs)."""
    x0 = abs(a)
    x1 = abs(b)
    mx = 0.0
    if x0 > mx:
        mx = x0
    if x1 > mx:
        mx = x1
    if math.isinf(mx):
        return mx
    if math.isnan(x0) or math.isnan(x1):
        return math.nan
    if mx == 0.0:
        return mx
    m, max_e = math.frexp(mx)
    if max_e < -1023:  # subnormal inputs: never met on a belt; CPython divides by max
        u = x0 / mx
        w = x1 / mx
        return mx * math.sqrt(u * u + w * w)
    scale = math.ldexp(1.0, -max_e)
    csum = 1.0
    frac1 = 0.0
    frac2 = 0.0
    frac3 = 0.0
    for k in range(2):
        x = x0 if k == 0 else x1
        x *= scale
        t = x * T27
        hi = t - (t - x)
        lo = x - hi
        x = hi * hi
        oldcsum = csum
        csum += x
        frac1 += (oldcsum - csum) + x
        x = 2.0 * hi * lo
        oldcsum = csum
        csum += x
        frac2 += (oldcsum - csum) + x
        frac3 += lo * lo
    h = math.sqrt(csum - 1.0 + (frac1 + frac2 + frac3))
    x = h
    t = x * T27
    hi = t - (t - x)
    lo = x - hi
    x = -hi * hi
    oldcsum = csum
    csum += x
    frac1 += (oldcsum - csum) + x
    x = -2.0 * hi * lo
    oldcsum = csum
    csum += x
    frac2 += (oldcsum - csum) + x
    x = -lo * lo
    oldcsum = csum
    csum += x
    frac3 += (oldcsum - csum) + x
    x = csum - 1.0 + (frac1 + frac2 + frac3)
    return (h + x / (2.0 * h)) / scale


@compiled(inline=True)
def py_pow(x: float, e: float) -> float:
    """``x ** e`` for finite x and a positive even-or-fractional e, as CPython's float_pow."""
    if x == 0.0:
        return 0.0
    x = abs(x)
    if x == 1.0:
        return 1.0
    return x**e


@compiled(inline=True)
def move_time(distance: float, speed: float, acceleration: float) -> float:
    """twin.geometry.move_time."""
    if acceleration <= 0.0:
        return distance / speed
    ramp = speed * speed / acceleration
    if distance >= ramp:
        return distance / speed + speed / acceleration
    return 2.0 * math.sqrt(distance / acceleration)


@compiled()
def _late(tt: float, dx: float, dy: float, v: float, v_r: float, acc: float) -> float:
    x = dx + v * tt
    return move_time(py_hypot(x, dy), v_r, acc) - tt


@compiled()
def intercept_time(dx: float, dy: float, v: float, v_r: float, acc: float) -> float:
    """twin.geometry.intercept_time."""
    a = v_r * v_r - v * v
    t = (dx * v + math.sqrt(dx * dx * v * v + a * (dx * dx + dy * dy))) / a
    if acc <= 0.0:
        return t
    lo = t
    s = v_r / acc
    if 1e-3 > s:
        s = 1e-3
    step = s / 8.0
    hi = lo + step
    closest = -dx / v if v != 0.0 else -math.inf  # the part passes nearest the tool
    if closest > lo and _late(closest, dx, dy, v, v_r, acc) <= 0.0:
        hi = closest  # late falls until then: the first meeting is before it
    else:
        while _late(hi, dx, dy, v, v_r, acc) > 0.0:
            lo, hi = hi, hi + step
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if _late(mid, dx, dy, v, v_r, acc) > 0.0:
            lo = mid
        else:
            hi = mid
    return hi


@compiled()
def place_intercept(dx: float, dy: float, u: float, v_r: float, acc: float) -> float:
    """twin.geometry.place_intercept: the pick's interception with the outfeed's signed
    velocity ``u``."""
    return intercept_time(dx, dy, u, v_r, acc)


@compiled()
def position_along(
    sx: float, sy: float, ex: float, ey: float, elapsed: float, speed: float, acc: float
) -> tuple[float, float]:
    """twin.geometry.position_along."""
    dist = py_hypot(ex - sx, ey - sy)
    if dist <= 0.0:
        return sx, sy
    total = move_time(dist, speed, acc)
    if elapsed >= total:
        return ex, ey
    if acc <= 0.0:
        done = speed * elapsed
    else:
        t_acc = speed / acc
        if total / 2.0 < t_acc:
            t_acc = total / 2.0
        v_top = acc * t_acc
        if elapsed <= t_acc:
            done = 0.5 * acc * elapsed * elapsed
        elif elapsed <= total - t_acc:
            done = 0.5 * v_top * t_acc + v_top * (elapsed - t_acc)
        else:
            left = total - elapsed
            done = dist - 0.5 * acc * left * left
    f = done / dist
    if 1.0 < f:
        f = 1.0
    return sx + f * (ex - sx), sy + f * (ey - sy)


@njit(cache=True, error_model="numpy")
def hypot_many(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """py_hypot over arrays (for tests)."""
    out = np.empty(a.size)
    for i in range(a.size):
        out[i] = py_hypot(a[i], b[i])
    return out


@njit(cache=True, error_model="numpy")
def pow_many(a: np.ndarray, e: float) -> np.ndarray:
    """py_pow over an array (for tests)."""
    out = np.empty(a.size)
    for i in range(a.size):
        out[i] = py_pow(a[i], e)
    return out
