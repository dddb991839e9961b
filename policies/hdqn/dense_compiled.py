""":class:`~.numpy_forward.NumpyQ`'s greedy action in one compiled call (for the students of the
lookahead, whose decisions must cost a small share of the planner's).

The same layers, the same float32 products and the same error bound as the numpy forward
pass: each output is a float32 sum of ``[x, 1] * [W | g|W|; b | g|b|]`` (in another order than
numpy's, which the bound allows: it holds for any order of the float32 sums), plus the input
error carried through ``(1 + g)|W|`` summed apart and added, as numpy adds its second
product. A ReLU whose sum lies below minus its bound is 0 in torch too, so its error is
0 (a bound tighter than numpy's, as sound), and zero inputs are skipped. A near tie still
returns -1 and the caller asks torch, so an action returned is torch's. numpy's dispatch
per product (tens of microseconds for a student's three layers and the bound) is what this
saves. The layers travel packed in flat arrays (:func:`pack`): numba
checks a handful of array arguments per call in a microsecond, a tuple of arrays far slower.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pnp_twin.twin.fast.jit import compiled

N_IN, N_OUT, WIDTH, AT_FUSED, AT_SPREAD, AT_OUT, RELU = range(7)


def pack(layers: list[Any]) -> tuple[np.ndarray, ...]:
    """The dense layers (``numpy_forward.Dense``) as :func:`greedy` reads them: the fused and
    spread matrices flattened, a table of sizes and offsets, and the float32 scratch."""
    table = np.zeros((len(layers), 7), np.int64)
    fused, spread, at_f, at_s, at_o = [], [], 0, 0, 0
    for i, layer in enumerate(layers):
        table[i] = (layer.fused.shape[0], layer.out, 2 * layer.out, at_f, at_s, at_o, layer.relu)
        fused.append(layer.fused.ravel())
        spread.append(layer.spread.ravel())
        at_f += layer.fused.size
        at_s += layer.spread.size
        at_o += layer.out + 1
    values = np.ones(at_o, np.float32)  # each layer's outputs and a 1 (the next bias's input)
    errors = np.zeros(at_o, np.float32)
    widest = max(layer.out for layer in layers)
    sums, carried = np.zeros(2 * widest, np.float32), np.zeros(widest, np.float32)
    return np.concatenate(fused), np.concatenate(spread), table, values, errors, sums, carried


@compiled()
def _rows(x: np.ndarray, n_in: int, w: np.ndarray, width: int, out: np.ndarray) -> None:
    """``out[:width] = x[:n_in] @ w[: n_in * width].reshape(n_in, width)`` in float32, each
    output summed over the inputs in order. Callers pass views, not offsets: with an offset
    in the index the compiler neither vectorises this loop nor drops the negative-index
    check (30 times slower, measured). Zero inputs are skipped (most of a student's ReLU
    outputs and errors): their products add nothing."""
    for o in range(width):
        out[o] = 0.0
    for i in range(n_in):
        xi = x[i]
        if xi == 0.0:
            continue
        row = i * width
        for o in range(width):
            out[o] += xi * w[row + o]


@compiled()
def greedy(
    x: np.ndarray,
    fused: np.ndarray,
    spread: np.ndarray,
    table: np.ndarray,
    values: np.ndarray,
    errors: np.ndarray,
    sums: np.ndarray,
    carried: np.ndarray,
) -> int:
    """The greedy action of input ``x`` (float32, >= 0, ending in a 1), or -1 for a near tie
    (the arrays of :func:`pack`)."""
    for layer in range(table.shape[0]):
        n_in, k, width = table[layer, N_IN], table[layer, N_OUT], table[layer, WIDTH]
        at_f, at_s, at_o = table[layer, AT_FUSED], table[layer, AT_SPREAD], table[layer, AT_OUT]
        if layer == 0:
            _rows(x, n_in, fused[at_f:], width, sums)
        else:  # numpy's second product err @ spread, added to the first
            last = table[layer - 1, AT_OUT]
            _rows(values[last:], n_in, fused[at_f:], width, sums)
            _rows(errors[last:], n_in - 1, spread[at_s:], k, carried)
        relu = table[layer, RELU] != 0
        for o in range(k):
            bound = sums[k + o] + carried[o] if layer > 0 else sums[k + o]
            acc = sums[o]
            if relu and np.float64(acc) + np.float64(bound) < 0.0:
                bound = np.float32(0.0)  # torch's sum is negative too: both ReLUs give 0
            errors[at_o + o] = bound
            values[at_o + o] = acc if not relu or acc > 0.0 else np.float32(0.0)
    last = table[table.shape[0] - 1, AT_OUT]
    k = table[table.shape[0] - 1, N_OUT]
    best = 0
    for o in range(1, k):
        if values[last + o] > values[last + best]:
            best = o
    low = np.float64(values[last + best]) - np.float64(errors[last + best])
    for o in range(k):
        if o != best and np.float64(values[last + o]) + np.float64(errors[last + o]) >= low:
            return -1
    return best
