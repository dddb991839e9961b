"""A replay window as an animated GIF, for e-mail and slides (``pnp-twin run --gif FILE``).

Each frame is drawn by :mod:`twin.picture`, the drawing the environments' ``render()`` uses,
from the positions :mod:`reports.replay_data` computes from the run's records (the page's
replay draws the same positions). Parts: white on the belt (their kind's colour on a line
with kinds), in their robot's colour once claimed, red when the line will lose them, grey
when no robot picks their kind; a bin turns amber during a box change; a tool has a black
centre while its robot is down. A line of text on top gives the clock and the running G.
Written with imageio (Pillow underneath): the ``gif`` extra.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from pnp_twin.reports.replay_data import FATES, STATES, parts_at, running_g, tools_at
from pnp_twin.twin import picture
from pnp_twin.twin.errors import UserError
from pnp_twin.twin.output import atomic_path

log = logging.getLogger(__name__)

FPS = 10
SPEED = 5.0  # simulated seconds per second of GIF
CHANGING: picture.RGB = (255, 183, 3)
DESIGN: picture.RGB = (163, 172, 185)
HEADER_PX = 22


def _rgb(hex_colour: str) -> picture.RGB:
    h = hex_colour.lstrip("#")
    return (int(h[0:2], 16), int(h[2:4], 16), int(h[4:6], 16))


def layout(data: Mapping[str, Any]) -> picture.Layout:
    """The layout of the replayed line (its outfeed included)."""
    belt = data["belt"]
    extra: tuple[float, ...] = ()
    of = data.get("outfeed")
    if of:
        extra = (of["y"] - of["width"] / 2, of["y"] + of["width"] / 2)
    return picture.Layout.of(
        belt["length"],
        belt["width"],
        [tuple(r["workspace"]) for r in data["robots"]],
        [tuple(r["bin"]) for r in data["robots"]],
        extra,
    )


def scene(data: Mapping[str, Any], t: float) -> picture.Scene:
    """What moves at ``t``, from the replay data."""
    p = data["parts"]
    tools = tools_at(data, t)
    where = parts_at(data, t)
    index = {pid: i for i, pid in enumerate(p["id"])}
    kind_rgb = [_rgb(c) for c in data["kindColours"]]
    out = picture.Scene()
    targets: dict[int, tuple[float, float]] = {}
    for pid, (x, y) in where.items():
        i = index[pid]
        claimed = p["decided"][i] is not None and p["decided"][i] <= t
        if p["fate"][i] == FATES.index("lost"):
            rgb = picture.LOST_PART
        elif p["fate"][i] == FATES.index("by design"):
            rgb = DESIGN
        elif claimed:
            rgb = picture.colour(p["robot"][i])
            if t < p["picked"][i]:
                targets[p["robot"][i]] = (x, y)
        else:
            rgb = kind_rgb[p["kind"][i]]
        out.parts.append((x, y, rgb))
    down = {s[0] for s in data["states"] if s[1] == STATES.index("down") and s[2] <= t < s[3]}
    changing = {s[0] for s in data["states"] if s[1] == len(STATES) and s[2] <= t < s[3]}
    for r, (x, y) in enumerate(tools):
        out.tools.append(picture.Tool(x, y, r, targets.get(r), r in down))
    for r in changing:
        bx, by = data["robots"][r]["bin"]
        out.boxes.append((bx - 0.07, by - 0.04, bx + 0.07, by + 0.04, CHANGING, True))
    of = data.get("outfeed")
    if of:
        out.boxes.extend(_containers(of, t))
    return out


def _containers(of: Mapping[str, Any], t: float) -> list[tuple[Any, ...]]:
    filled = {(c, k) for c, k, at in of["fills"] if at <= t}
    half_l, half_w = of["length"] / 2, of["width"] / 2
    boxes: list[tuple[Any, ...]] = []
    for j, at in enumerate(of["times"]):
        cx = of["xIn"] + of["u"] * (t - at)
        if at > t or not of["lo"] - half_l <= cx <= of["hi"] + half_l:
            continue
        y = of["y"]
        boxes.append((cx - half_l, y - half_w, cx + half_l, y + half_w, (140, 109, 49), False))
        for k, (dx, dy) in enumerate(zip(of["dx"], of["dy"], strict=True)):
            rgb = (42, 157, 143) if (of["first"] + j, k) in filled else (200, 200, 200)
            s = 0.015
            boxes.append((cx + dx - s, y + dy - s, cx + dx + s, y + dy + s, rgb, True))
    return boxes


def frames(data: Mapping[str, Any], fps: int = FPS, speed: float = SPEED) -> list[np.ndarray]:
    """The GIF's frames over the replay window: ``speed`` simulated seconds per second."""
    from PIL import Image, ImageDraw

    look = layout(data)
    base = picture.background(look)
    out = []
    for t in np.arange(data["t0"], data["t1"] + 1e-9, speed / fps):
        img = picture.draw(look, scene(data, float(t)), base)
        pic = Image.new("RGB", (img.shape[1], img.shape[0] + HEADER_PX), (255, 255, 255))
        pic.paste(Image.fromarray(img), (0, HEADER_PX))
        picked, lost = running_g(data, float(t))
        g = f"{100 * picked / (picked + lost):.1f} %" if picked + lost else "-"
        text = f"{data.get('title', '')}   t = {t:6.1f} s   G = {g} ({picked} picked, {lost} lost)"
        ImageDraw.Draw(pic).text((6, 5), text, fill=(29, 39, 51))
        out.append(np.asarray(pic))
    return out


def write_gif(data: Mapping[str, Any], path: Path | str, fps: int = FPS) -> Path:
    """Write the replay window as an animated GIF to ``path`` atomically; returns the path."""
    try:
        import imageio.v3 as iio
    except ImportError:
        raise UserError("--gif needs imageio and Pillow: pip install 'pnp-twin[gif]'") from None
    pictures = frames(data, fps)
    with atomic_path(path) as tmp:
        iio.imwrite(tmp, np.stack(pictures), extension=".gif", duration=1000 / fps, loop=0)
    log.info("GIF of %d frames written to %s", len(pictures), path)
    return Path(path)
