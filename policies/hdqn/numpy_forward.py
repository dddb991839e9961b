"""The Q-network's forward pass in numpy, one decision at a time, with a proof that its
greedy action is torch's.

A learned policy asks its network for one observation per decision; through torch that
costs a hundred or more microseconds of dispatch for a network of a few ten thousand
multiply-adds. :class:`NumpyQ` copies the weights of a small fully connected
:class:`~pnp_twin.policies.hdqn.network.QNetwork` (the ``compact`` preset on a robot's
window: flatten, the extras concatenated, linear and ReLU layers) once and evaluates the same
layers with numpy, in float32 as torch does. Convolutional trunks
(``paper``, ``pooled``) and networks over :data:`MAX_WEIGHTS` stay on torch, which is
faster there.

The greedy action must be torch's although the two sum in different orders. A dot product
of ``n`` terms plus a bias, summed in any order, is within ``gamma(n + 1) * (sum |w_i x_i| +
|b|)`` of its exact value (``gamma(n) = n u / (1 - n u)``, ``u = 2**-24`` for float32;
Higham, *Accuracy and Stability of Numerical Algorithms*, 3.1), torch's sum and this one
alike; an error ``e`` already in the inputs adds at most ``|W| e``, and ReLU does not
increase it. So the forward pass carries a bound ``E`` on the distance between its values
and torch's, and when the best action's value minus its bound exceeds every other value
plus its own, torch's values rank the same action first (a tie in torch would go to the
lowest index; within the bounds there is none). Every layer's input is non-negative (the
occupancy image, the one-hot, ReLU outputs), so one product ``[x, 1] @ [[W, g |W|], [b,
g |b|]]`` per layer gives the values and the bound's sums alike.

When it cannot decide (a near tie) :meth:`NumpyQ.greedy` returns ``None`` and the caller
asks torch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

U32 = 2.0**-24  # unit roundoff of float32
_ONE = np.ones(1, np.float32)


class Unsupported(ValueError):
    """The network holds a layer this module does not evaluate (torch then does)."""


def gamma(n: int) -> float:
    """Higham's ``gamma_n`` for float32: the relative error bound of ``n`` roundings."""
    return n * U32 / (1.0 - n * U32)


MAX_WEIGHTS = 100_000
"""Larger networks stay on torch: numpy's products with ``[W | |W|]`` and the bound's matrix
cost more than torch's (the ``single`` preset's 1,296 joint actions: 250,000 weights)."""


@dataclass(frozen=True)
class Dense:
    """One linear layer (and the ReLU after it, if any) as float32 arrays, with the bound's
    constants folded in (every factor rounded up)."""

    fused: np.ndarray  # (in + 1, 2 out) float32: [[W, g |W|], [b, g |b|]]; see forward
    spread: np.ndarray  # (in, out): (1 + g) |W|, so e @ spread bounds what e moves
    out: int
    relu: bool = False


def _float32(t: Any) -> np.ndarray:
    import torch

    if not isinstance(t, torch.Tensor) or t.dtype != torch.float32:
        raise Unsupported("the bound assumes float32 weights")
    return np.array(t.detach().cpu().numpy(), dtype=np.float32, copy=True)


def _up(a: np.ndarray | float) -> np.ndarray:
    """``a`` as float32, rounded up (never below the float64 value)."""
    a32 = np.asarray(a, dtype=np.float32)
    return np.where(a32.astype(np.float64) < a, np.nextafter(a32, np.float32(np.inf)), a32)


def _dense(m: Any) -> Dense:
    w = _float32(m.weight).T  # (in, out)
    b = _float32(m.bias) if m.bias is not None else np.zeros(w.shape[1], np.float32)
    n = w.shape[0] + 1
    g = 2.0 * gamma(n)  # torch's float32 sum and this float32 sum, each from the exact
    # |y_torch - y| <= |W| e + g (|W| x + |W| e + |b|) = (1 + g) |W| e + g |W| x + g |b|,
    # computed here in float32 too: each factor grown by 1 / (1 - gamma(n + 3)) so that the
    # float32 sums and products (n + 3 roundings deep, all terms >= 0) stay above it
    safe = 1.0 + 2.0 * gamma(n + 3)
    w64 = np.abs(w.astype(np.float64))
    values = np.concatenate([w, b[None, :]])
    bound = _up(np.concatenate([w64, np.abs(b.astype(np.float64))[None, :]]) * (g * safe))
    return Dense(
        fused=np.ascontiguousarray(np.concatenate([values, bound], axis=1)),
        spread=np.ascontiguousarray(_up(w64 * ((1.0 + g) * safe))),
        out=w.shape[1],
    )


def dense_layers(network: Any) -> list[Dense]:
    """The layers of a fully connected QNetwork, or :class:`Unsupported`."""
    from torch import nn

    trunk = list(network.trunk)
    if len(trunk) != 1 or not isinstance(trunk[0], nn.Flatten) or trunk[0].start_dim != 1:
        raise Unsupported("a convolutional trunk (torch evaluates it)")
    layers: list[Dense] = []
    for m in network.head:
        if isinstance(m, nn.ReLU) and layers and not layers[-1].relu:
            layers[-1] = replace(layers[-1], relu=True)
        elif isinstance(m, nn.Linear):
            layers.append(_dense(m))
        else:
            raise Unsupported(f"{type(m).__name__} here has no numpy forward")
    if not layers or layers[-1].relu:
        raise Unsupported("the network must end in a linear layer")
    if sum(layer.spread.size for layer in layers) > MAX_WEIGHTS:
        raise Unsupported(f"over {MAX_WEIGHTS} weights (torch is faster)")
    return layers


class NumpyQ:
    """The forward pass of a fully connected QNetwork in numpy, from a copy of its weights
    taken at construction (see the module docstring); :class:`Unsupported` otherwise."""

    def __init__(self, network: Any, compiled: bool = False) -> None:
        self.layers = dense_layers(network)
        self.n_extra = int(network.n_extra)
        self.n_in = self.layers[0].fused.shape[0]  # inputs and the bias's 1
        self._buffers = [np.ones(layer.out + 1, np.float32) for layer in self.layers]
        self.undecided = 0  # near ties handed back to torch
        self.compiled = compiled
        """Greedy actions by :mod:`.dense_compiled` (one call instead of numpy's products)."""
        if compiled:
            from pnp_twin.policies.hdqn.dense_compiled import greedy, pack

            self._packed = pack(self.layers)
            self._compiled_greedy = greedy  # looked up once, not per decision

    def inputs(self, obs: np.ndarray, extra: np.ndarray | None = None) -> np.ndarray:
        """The first layer's input (exact, >= 0): the image flattened, the extras (the
        robot's one-hot) after it, and a 1 (the bias's input)."""
        obs = np.asarray(obs)
        parts = [obs.reshape(-1), _ONE]
        if self.n_extra:
            assert extra is not None, "this network needs the extra features (robot one-hot)"
            extra = np.asarray(extra)
            parts.insert(1, extra.reshape(-1))
            if extra.min(initial=0.0) < 0.0:
                raise ValueError("the bound needs extras >= 0 (a one-hot)")
        x = np.concatenate(parts, dtype=np.float32)
        if x.shape[0] != self.n_in:
            raise ValueError(f"the network takes {self.n_in - 1} inputs, got {x.shape[0] - 1}")
        if obs.dtype.kind != "u" and obs.min(initial=0) < 0:
            raise ValueError("the bound needs inputs >= 0 (an occupancy image)")
        return x

    def forward(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Q-values of input ``x`` (ending in a 1) and a bound per value on |torch's - these|.

        Every layer's input is >= 0 (the image, the one-hot, ReLU outputs), so one product
        ``[x, 1] @ [[W, g |W|], [b, g |b|]]`` gives the values ``W x + b`` and the bound's
        ``g (|W| x + |b|)``; with the bound ``e`` on the input's error, torch's output
        differs from these by at most that plus ``(1 + g) |W| e`` (every factor rounded up
        in :func:`_dense`). Matrix-vector products only: numpy's matrix product of two rows
        costs more (BLAS threads it).
        """
        err: np.ndarray | None = None  # the inputs are exact
        for layer, buffer in zip(self.layers, self._buffers, strict=True):
            z = x @ layer.fused
            k = layer.out
            bound = z[k:]
            if err is not None:
                bound += err @ layer.spread
            err = bound
            if layer.relu:  # into the next layer's input, whose last entry stays 1
                np.maximum(z[:k], 0.0, out=buffer[:k])
                x = buffer
            else:
                x = z[:k]
        assert err is not None
        return x, err

    def q_values(self, obs: np.ndarray, extra: np.ndarray | None = None) -> np.ndarray:
        """Q-values ``(n_actions,)`` of one observation."""
        return self.forward(self.inputs(obs, extra))[0]

    def greedy_input(self, x: np.ndarray) -> int | None:
        """:meth:`greedy` of a first-layer input the caller built (float32, every entry >= 0,
        ending in a 1), by the compiled pass (``compiled=True``)."""
        action = self._compiled_greedy(x, *self._packed)
        if action >= 0:
            return int(action)
        self.undecided += 1
        return None

    def greedy(self, obs: np.ndarray, extra: np.ndarray | None = None) -> int | None:
        """Torch's greedy action for one observation, or ``None`` when the values are too
        close to rank without torch's own arithmetic."""
        if self.compiled:
            return self.greedy_input(self.inputs(obs, extra))
        q, err = self.forward(self.inputs(obs, extra))
        best = int(q.argmax())
        q = q.astype(np.float64)
        err = err.astype(np.float64)
        above = q + err
        above[best] = -math.inf
        if q[best] - err[best] > above.max():
            return best
        self.undecided += 1
        return None
