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

Both read the line (belt, robots, gateway) and never change it. The picture is drawn by
:mod:`twin.picture`, the one drawing of the line the replay's GIF export uses too.
"""

from __future__ import annotations

from bisect import bisect_left, bisect_right
from typing import TYPE_CHECKING

import numpy as np

from pnp_twin.twin import picture

if TYPE_CHECKING:
    from pnp_twin.twin.line import Line

RENDER_MODES = ["human", "rgb_array", "ansi"]
"""``human`` prints the ``ansi`` text view to standard output at each :meth:`render` (and
returns None, as Gymnasium and PettingZoo ask)."""
RENDER_FPS = 10
"""Frames per second a video of the decision epochs plays at (one frame per env step)."""
colour = picture.colour
PX_PER_M = picture.PX_PER_M


def _on_belt(line: Line) -> tuple[range, float]:
    belt, now = line.belt, line.env.now
    lo = bisect_left(belt.fed, now - belt.length / belt.speed)
    hi = bisect_right(belt.fed, now)
    return range(lo, hi), now


def layout(line: Line) -> picture.Layout:
    """What does not move on ``line``, as :mod:`twin.picture` draws it."""
    belt = line.belt
    return picture.Layout.of(
        belt.length,
        belt.width,
        [(r.a, r.b) for r in line.robots],
        [r.bin.position for r in line.robots],
    )


def scene(line: Line) -> picture.Scene:
    """What moves on ``line`` now: free parts white, a claimed part in its robot's colour,
    each tool joined to the part it is going for."""
    belt = line.belt
    parts, now = _on_belt(line)
    v = belt.speed
    out = picture.Scene()
    for i in parts:
        if belt.left_at[i] > now:
            holder = belt.holder[i]
            rgb = picture.FREE_PART if holder < 0 else colour(holder)
            out.parts.append((v * (now - belt.fed[i]), belt.y[i], rgb))
    for r in line.robots:
        target = None
        if r.claimed >= 0:
            target = (v * (now - belt.fed[r.claimed]), belt.y[r.claimed])
        out.tools.append(picture.Tool(r.tool[0], r.tool[1], r.index, target, r.down))
    return out


def background(line: Line) -> np.ndarray:
    """What does not move: the belt, the workspaces and the bins (drawn once per line)."""
    return picture.background(layout(line))


def frame(line: Line, base: np.ndarray | None = None) -> np.ndarray:
    """The top view of ``line`` now, ``(H, W, 3)`` uint8 (see the module docstring);
    ``base`` is :func:`background` of the line, when the caller keeps it between frames."""
    return picture.draw(layout(line), scene(line), base)


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
