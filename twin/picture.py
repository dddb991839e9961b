"""The line seen from above as an RGB image: the one pixel drawing of the line.

The environments' ``render()`` (``learning/envs/render.py``, from a live line) and the
replay's GIF export (``reports/replay_gif.py``, from a run's records) both describe what to
draw as a :class:`Layout` (what does not move) and a :class:`Scene` (what moves, at one
instant) and draw it here, so the two pictures cannot drift apart.

x runs along the image to the right (feeder on the left), y up; :data:`PX_PER_M` pixels per
metre. The belt is dark grey with each robot's workspace tinted in the robot's colour; bins
are outlined boxes; parts are small squares, tools larger ones in their robot's colour (a
black centre while the robot is down), joined by a line to the part they are going for.
Numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

PX_PER_M = 320
MARGIN = 0.06  # m around the drawing
PART = 0.012  # m, half the side of a part's square
TOOL = 0.02  # m, half the side of a tool's square

RGB = tuple[int, int, int]
BACKGROUND: RGB = (236, 236, 236)
BELT: RGB = (70, 70, 70)
FREE_PART: RGB = (255, 255, 255)
LOST_PART: RGB = (230, 57, 70)
COLOURS: list[RGB] = [
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (23, 190, 207),
]


def colour(robot: int) -> RGB:
    """The drawing colour of a 0-based robot."""
    return COLOURS[robot % len(COLOURS)]


@dataclass(frozen=True)
class Layout:
    """What does not move: the belt, each robot's workspace and bin, the drawn y range."""

    length: float
    width: float
    workspaces: tuple[tuple[float, float], ...]
    bins: tuple[tuple[float, float], ...]
    y_lo: float
    y_hi: float

    @classmethod
    def of(
        cls,
        length: float,
        width: float,
        workspaces: list[tuple[float, float]],
        bins: list[tuple[float, float]],
        extra_ys: tuple[float, ...] = (),
    ) -> Layout:
        """The layout of a line; the y range covers the belt, every bin and ``extra_ys``."""
        ys = [b[1] for b in bins] + list(extra_ys)
        return cls(
            length,
            width,
            tuple(workspaces),
            tuple(bins),
            min([0.0, *(y - 0.06 for y in ys)]),
            max([width, *(y + 0.06 for y in ys)]),
        )


@dataclass(frozen=True)
class Tool:
    """A robot's tool at one instant: where, whose, the point it heads for, whether down."""

    x: float
    y: float
    robot: int
    target: tuple[float, float] | None = None
    down: bool = False


@dataclass
class Scene:
    """What moves, at one instant: parts (x, y, colour), tools, and outlined boxes (x0, y0,
    x1, y1, colour, filled) such as an outfeed's containers or a bin being changed."""

    parts: list[tuple[float, float, RGB]] = field(default_factory=list)
    tools: list[Tool] = field(default_factory=list)
    boxes: list[tuple[float, float, float, float, RGB, bool]] = field(default_factory=list)


class Canvas:
    """An RGB image addressed in metres (x right, y up)."""

    def __init__(self, layout: Layout, img: np.ndarray | None = None) -> None:
        self.x0, self.y_hi = -MARGIN, layout.y_hi + MARGIN
        if img is None:
            width = int(round((layout.length + 2 * MARGIN) * PX_PER_M))
            height = int(round((layout.y_hi - layout.y_lo + 2 * MARGIN) * PX_PER_M))
            img = np.full((height, width, 3), BACKGROUND, dtype=np.uint8)
        self.img = img

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


def background(layout: Layout) -> np.ndarray:
    """What does not move: the belt, the workspaces and the bins (drawn once per line)."""
    canvas = Canvas(layout)
    canvas.rect(0.0, 0.0, layout.length, layout.width, BELT)
    for i, ((a, b), (bx, by)) in enumerate(zip(layout.workspaces, layout.bins, strict=True)):
        tint = tuple(int(0.35 * c + 0.65 * BELT[0]) for c in colour(i))
        canvas.rect(a, 0.0, min(b, layout.length), layout.width, tint)
        canvas.outline(bx - 0.08, by - 0.05, bx + 0.08, by + 0.05, colour(i))
    return canvas.img


def draw(layout: Layout, scene: Scene, base: np.ndarray | None = None) -> np.ndarray:
    """The picture of ``scene`` on ``layout``, ``(H, W, 3)`` uint8; ``base`` is
    :func:`background` of the layout, when the caller keeps it between frames."""
    canvas = Canvas(layout, (background(layout) if base is None else base).copy())
    for x0, y0, x1, y1, rgb, filled in scene.boxes:
        (canvas.rect if filled else canvas.outline)(x0, y0, x1, y1, rgb)
    for x, y, rgb in scene.parts:
        canvas.box(x, y, PART, rgb)
    for tool in scene.tools:
        if tool.target is not None:
            canvas.segment((tool.x, tool.y), tool.target, colour(tool.robot))
        canvas.box(tool.x, tool.y, TOOL, colour(tool.robot))
        if tool.down:
            canvas.box(tool.x, tool.y, TOOL / 2, (0, 0, 0))
    return canvas.img
