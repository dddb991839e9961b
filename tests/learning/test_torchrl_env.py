"""The TorchRL env over the compiled multi-agent vector env, TorchRL's PettingZooWrapper with
the mask, and a TorchRL IPPO run end to end."""

from __future__ import annotations

import time

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("torchrl")

from torchrl.envs.utils import check_env_specs  # noqa: E402

from pnp_twin.learning.envs import torchrl_env  # noqa: E402

SHORT = {"overrides": {"duration": 20.0, "warmup": 2.0}}


def _rollout(seed: int, steps: int = 120):
    env = torchrl_env("baseline", num_envs=3, **SHORT)
    env.set_seed(seed)
    torch.manual_seed(seed)
    return env, env.rollout(steps, break_when_any_done=False)


def test_check_env_specs_task_and_scenario():
    check_env_specs(torchrl_env("baseline", num_envs=3, **SHORT), seed=0)
    check_env_specs(torchrl_env("paper_baseline", num_envs=2, termination="t_continue"), seed=1)


def test_masks_in_specs_and_rollout_draws_only_allowed_actions():
    env, td = _rollout(0)
    assert ("agents", "action_mask") in env.observation_spec.keys(True)
    mask, action = td["agents", "action_mask"], td["agents", "action"]
    assert mask.shape == (3, 120, 4, 5) and action.shape == (3, 120, 4)
    allowed = mask.gather(-1, action[..., None]).squeeze(-1)
    assert bool(allowed.all())  # rand_step draws from the masked action spec
    assert not bool(mask.all())  # robots without a choice: rule 0 only
    assert float(td["next", "tau"].min()) > 0.0


def test_same_seed_same_rollout_and_lines_reset_after_their_end():
    _, a = _rollout(5, 400)
    _, b = _rollout(5, 400)
    assert torch.equal(a["next", "agents", "reward"], b["next", "agents", "reward"])
    assert torch.equal(a["agents", "observation"], b["agents", "observation"])
    _, c = _rollout(6, 400)
    assert not torch.equal(a["next", "agents", "reward"], c["next", "agents", "reward"])
    done = a["next", "done"].squeeze(-1)
    assert bool((done.sum(dim=1) >= 1).all())  # every 20 s line ended within 400 steps
    e, t = np.argwhere(done.numpy())[0]
    # reset by the rollout: the line runs on from a fresh start (G counts again from 0 parts)
    assert float(a["next", "tau"][e, t + 1]) > 0.0
    assert float(a["next", "gripping_rate"][e, t + 1]) != float(a["next", "gripping_rate"][e, t])


def test_pettingzoo_wrapper_with_mask_in_observation():
    from torchrl.envs.libs.pettingzoo import PettingZooWrapper

    from pnp_twin.learning.envs.pz_parallel import PickPlaceParallel
    from pnp_twin.learning.envs.torchrl_pz import pettingzoo_torchrl

    with pytest.raises(TypeError):  # TorchRL's own wrapper, as it is (torchrl 0.14.1)
        PettingZooWrapper(PickPlaceParallel(mask_in_observation=True, **SHORT)).reset(seed=0)
    env = pettingzoo_torchrl(**SHORT)
    check_env_specs(env, seed=0)
    torch.manual_seed(0)
    td = env.rollout(40)
    mask, action = td["agents", "action_mask"], td["agents", "action"]
    assert bool(mask.gather(-1, action[..., None]).all()) and not bool(mask.all())


@pytest.mark.timeout(120)
def test_torchrl_ippo_runs_end_to_end():
    from examples.torchrl_ippo import Args, main

    t0 = time.perf_counter()
    log = main(Args(frames=4096, num_envs=16, steps_per_batch=64, duration=20.0, epochs=2))
    assert len(log) == 4 and all(np.isfinite(r["loss"]) for r in log)
    assert sum(r["episodes"] for r in log) >= 16  # every line ended at least once
    assert time.perf_counter() - t0 < 60.0


def test_flat_observations_for_mlps():
    env = torchrl_env("slow_robot-v1", num_envs=2, flatten=True, **SHORT)
    check_env_specs(env, seed=0)
    td = env.reset()
    assert td["agents", "observation"].shape == (2, 4, 8 * 7)
    assert td["state"].shape == (2, 8 * 64)
