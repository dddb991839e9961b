"""Rendering a line for the environments: a top-view RGB frame and a text view.

``rgb_array`` (:func:`frame`): the line seen from above, x along the image to the right
(feeder on the left), y up. The belt is dark grey with each robot's workspace tinted in the
robot's colour; free parts are white squares, a claimed part is drawn in its robot's colour;
each robot's tool is a filled square in its colour (a black centre while it is down), joined
by a line to the part it is going for; bins are outlined boxes above the belt. The size
follows the belt: :data:`PX_PER_M` pixels per metre (about 800 x 180 px on paper_baseline).

``ansi`` (:func:`text`), also printed by ``human``: one header line (simulated time, free
robots, gripping rate) and the belt's observation grid, one text row per grid row with the
upper (bin) edge on top: ``.`` empty, ``o`` a part, ``1``..``9`` a part claimed by that robot;
a ruler line marks the workspaces.

Both read the line (belt, robots, gateway) and never change it.
"""

from __future__ import annotations

from bisect import bisect_left, bisect_right
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from pnp_twin.twin.line import Line

RENDER_MODES = ["human", "rgb_array", "ansi"]
"""``human`` prints the ``ansi`` text view to standard output at each :meth:`render` (and
returns None, as Gymnasium and PettingZoo ask)."""
RENDER_FPS = 10
"""Frames per second a video of the decision epochs plays at (one frame per env step)."""
PX_PER_M = 320
MARGIN = 0.06  # m around the drawing
PART = 0.012  # m, half the side of a part's square
TOOL = 0.02  # m, half the side of a tool's square

BACKGROUND = (236, 236, 236)
BELT = (70, 70, 70)
FREE_PART = (255, 255, 255)
COLOURS = [
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (23, 190, 207),
]


def colour(robot: int) -> tuple[int, int, int]:
    """The drawing colour of a 0-based robot."""
    return COLOURS[robot % len(COLOURS)]


class _Canvas:
    """An RGB image addressed in metres (x right, y up)."""

    def __init__(self, x_hi: float, y_lo: float, y_hi: float) -> None:
        self.x0, self.y_hi = -MARGIN, y_hi + MARGIN
        width = int(round((x_hi + 2 * MARGIN) * PX_PER_M))
        height = int(round((y_hi - y_lo + 2 * MARGIN) * PX_PER_M))
        self.img = np.full((height, width, 3), BACKGROUND, dtype=np.uint8)

    def px(self, x: float, y: float) -> tuple[int, int]:
        """(row, column) of a point."""
        return int((self.y_hi - y) * PX_PER_M), int((x - self.x0) * PX_PER_M)

    def rect(self, x0: float, y0: float, x1: float, y1: float, rgb: tuple[int, ...]) -> None:
        r1, c0 = self.px(x0, y0)
        r0, c1 = self.px(x1, y1)
        h, w = self.img.shape[:2]
        self.img[max(r0, 0) : min(r1 + 1, h), max(c0, 0) : min(c1 + 1, w)] = rgb

    def box(self, x: float, y: float, half: float, rgb: tuple[int, ...]) -> None:
        self.rect(x - half, y - half, x + half, y + half, rgb)

    def outline(self, x0: float, y0: float, x1: float, y1: float, rgb: tuple[int, ...]) -> None:
        t = 1.5 / PX_PER_M
        for a, b, c, d in (
            (x0, y0, x1, y0 + t),
            (x0, y1 - t, x1, y1),
            (x0, y0, x0 + t, y1),
            (x1 - t, y0, x1, y1),
        ):
            self.rect(a, b, c, d, rgb)

    def segment(self, p: tuple[float, float], q: tuple[float, float], rgb: tuple[int, ...]) -> None:
        n = max(2, int(np.hypot(q[0] - p[0], q[1] - p[1]) * PX_PER_M))
        s = np.linspace(0.0, 1.0, n)
        rows = ((self.y_hi - (p[1] + s * (q[1] - p[1]))) * PX_PER_M).astype(np.intp)
        cols = ((p[0] + s * (q[0] - p[0]) - self.x0) * PX_PER_M).astype(np.intp)
        h, w = self.img.shape[:2]
        inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
        self.img[rows[inside], cols[inside]] = rgb


def _on_belt(line: Line) -> tuple[range, float]:
    belt, now = line.belt, line.env.now
    lo = bisect_left(belt.fed, now - belt.length / belt.speed)
    hi = bisect_right(belt.fed, now)
    return range(lo, hi), now


def background(line: Line) -> np.ndarray:
    """What does not move: the belt, the workspaces and the bins (drawn once per line)."""
    belt = line.belt
    bins_top = max(r.bin.position[1] for r in line.robots) + 0.06
    canvas = _Canvas(belt.length, 0.0, bins_top)
    canvas.rect(0.0, 0.0, belt.length, belt.width, BELT)
    for r in line.robots:
        tint = tuple(int(0.35 * c + 0.65 * BELT[0]) for c in colour(r.index))
        canvas.rect(r.a, 0.0, min(r.b, belt.length), belt.width, tint)
        bx, by = r.bin.position
        canvas.outline(bx - 0.08, by - 0.05, bx + 0.08, by + 0.05, colour(r.index))
    return canvas.img


def frame(line: Line, base: np.ndarray | None = None) -> np.ndarray:
    """The top view of ``line`` now, ``(H, W, 3)`` uint8 (see the module docstring);
    ``base`` is :func:`background` of the line, when the caller keeps it between frames."""
    belt = line.belt
    bins_top = max(r.bin.position[1] for r in line.robots) + 0.06
    canvas = _Canvas.__new__(_Canvas)
    canvas.x0, canvas.y_hi = -MARGIN, bins_top + MARGIN
    canvas.img = (background(line) if base is None else base).copy()
    parts, now = _on_belt(line)
    v = belt.speed
    for i in parts:
        if belt.left_at[i] > now:
            holder = belt.holder[i]
            rgb = FREE_PART if holder < 0 else colour(holder)
            canvas.box(v * (now - belt.fed[i]), belt.y[i], PART, rgb)
    for r in line.robots:
        tx, ty = r.tool
        if r.claimed >= 0:
            part = r.claimed
            canvas.segment((tx, ty), (v * (now - belt.fed[part]), belt.y[part]), colour(r.index))
        canvas.box(tx, ty, TOOL, colour(r.index))
        if r.down:
            canvas.box(tx, ty, TOOL / 2, (0, 0, 0))
    return canvas.img


def text(line: Line, gripping_rate: float | None = None) -> str:
    """The ``ansi`` view of ``line`` now (see the module docstring)."""
    belt = line.belt
    nx, ny = belt.grid
    cells = [["."] * nx for _ in range(ny)]
    parts, now = _on_belt(line)
    for i in parts:
        if belt.left_at[i] > now:
            col = min(int(belt.speed * (now - belt.fed[i]) / belt.cell), nx - 1)
            row = min(int(belt.y[i] / belt.width * ny), ny - 1)
            holder = belt.holder[i]
            cells[row][col] = "o" if holder < 0 else str((holder + 1) % 10)
    ruler = [" "] * nx
    for r in line.robots:
        a, b = int(r.a / belt.cell), min(int(r.b / belt.cell), nx) - 1
        for c in range(a, b + 1):
            ruler[c] = "-"
        ruler[a], ruler[b] = "|", "|"
        ruler[(a + b) // 2] = str((r.index + 1) % 10)
    free = ",".join(str(r + 1) for r in sorted(line.gateway.pending)) or "-"
    head = f"t={now:8.2f} s  free robots: {free}"
    if gripping_rate is not None:
        head += f"  G={gripping_rate:5.1f} %"
    rows = ["".join(row) for row in reversed(cells)]
    return "\n".join([head, *rows, "".join(ruler)]) + "\n"
