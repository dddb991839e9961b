"""twin.camera: the belt image of a hand-loaded belt, cell by cell, channel by channel."""

from __future__ import annotations

import numpy as np
import pytest

from pnp_twin.twin.belt import Belt
from pnp_twin.twin.camera import BeltCamera
from pnp_twin.twin.scenario import Scenario

# A 2 m belt at 0.5 m/s, 20 x 4 cells of 0.1 m; robots on [0.5, 1.0] and [1.0, 1.45].
SCENARIO = Scenario.model_validate(
    {
        "belt": {"length": 2.0, "width": 0.4, "speed": 0.5, "grid": [20, 4]},
        "robots": {"count": 2, "workspaces": [[0.5, 1.0], [1.0, 1.45]]},
    }
)
FED = [0.0, 0.5, 1.0, 3.9]
YS = [0.05, 0.15, 0.39, 0.2]


def camera(channels: int) -> tuple[BeltCamera, Belt]:
    belt = Belt(2.0, 0.4, 0.5, (20, 4), end=1.45)
    belt.load(np.array(FED), np.array(YS))
    belt.put(3)  # the part fed at 3.9 is not on the belt yet
    cam = BeltCamera(SCENARIO, channels)
    cam.attach(belt)
    return cam, belt


def cells(image: np.ndarray) -> list[tuple[int, int]]:
    rows, cols = np.nonzero(image)
    return sorted(zip(rows.tolist(), cols.tolist(), strict=True))


def test_windows_start_at_each_workspace_and_share_the_widest_width():
    cam, _ = camera(1)
    assert cam.starts == [5, 10] and cam.window_width == 5
    assert cam.spans == [(5, 10), (10, 15)]
    assert cam.shape == (1, 4, 20) and cam.window_shape == (1, 4, 5)


def test_parts_are_drawn_where_they_are_until_gripped():
    cam, belt = camera(2)
    # at t = 2: x = 1.0, 0.75, 0.5 -> columns 10, 7, 5; rows 0, 1, 3
    image = cam.belt(2.0)
    assert image.shape == (2, 4, 20)
    assert cells(image[0]) == [(0, 10), (1, 7), (3, 5)] and not image[1].any()
    belt.claim(1, robot=0, grip_at=2.5)
    image = cam.belt(2.2)  # x = 1.1, 0.85, 0.6
    assert cells(image[0]) == [(0, 11), (1, 8), (3, 6)] and cells(image[1]) == [(1, 8)]
    assert cells(cam.belt(2.5)[0]) == [(0, 12), (3, 7)]  # part 1 gripped at 2.5


def test_the_busy_channel_marks_the_workspaces_of_robots_that_are_not_free():
    cam, _ = camera(3)
    busy = cam.belt(2.0, free=[1])[2]
    assert busy[:, 5:10].all() and not busy[:, :5].any() and not busy[:, 10:].any()
    assert cam.belt(2.0, free=[0, 1])[2].sum() == 0


def test_a_window_is_its_slice_of_the_belt_and_drawn_once_per_epoch():
    cam, belt = camera(1)
    whole = cam.belt(2.0)
    assert np.array_equal(cam.window(1, 2.0, epoch=1), whole[:, :, 10:15])
    assert np.array_equal(cam.window(0, 2.0, epoch=1), whole[:, :, 5:10])
    belt.claim(0, robot=1, grip_at=2.0)  # gripped now: gone from the belt
    assert np.array_equal(cam.window(1, 2.0, epoch=1), whole[:, :, 10:15])  # same epoch
    assert not cam.window(1, 2.0, epoch=2).any()  # a new epoch draws again


def test_a_bad_channel_count_is_refused():
    with pytest.raises(ValueError, match="channels: 4"):
        BeltCamera(SCENARIO, 4)
