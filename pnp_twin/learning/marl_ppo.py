"""IPPO and MAPPO on the multi-agent compiled vector env, with TorchRL's building blocks.

The algorithm's parts are TorchRL's (the ``marl`` extra, ``torchrl>=0.7``): the agents'
networks are :class:`torchrl.modules.MultiAgentMLP` (parameters shared across agents, an
agent's one-hot id in its input), the policy a :class:`torchrl.modules.ProbabilisticActor`
over a :class:`torchrl.modules.MaskedCategorical` (the env's action mask: a robot with no
candidate part, or one that is not deciding, can only take rule 0), the loss
:class:`torchrl.objectives.ClipPPOLoss` and the advantages TorchRL's
:func:`~torchrl.objectives.value.functional.generalized_advantage_estimate`. This module
adds what is specific to the line: the rollout over
:class:`~pnp_twin.learning.envs.vector_marl.PickPlaceParallelVectorEnv` (numpy in, tensors
out), the semi-MDP discount and the features.

- **IPPO**: each agent's critic sees what its actor sees (its workspace window, its id, its
  mask). **MAPPO**: the critic sees the global state (the whole belt image,
  ``env.state()``) and the agent's id: centralised training, decentralised execution.
- **Semi-MDP.** Every agent is stepped at every env step (a non-deciding agent's action is
  forced by its mask, log-probability 0, so it adds no policy gradient); a step lasts
  ``info["tau"]`` simulated seconds and is discounted by ``gamma ** tau`` (``gamma`` per
  simulated second), passed to GAE as a per-step discount (docs/semi_mdp.md).
- **Unmasked** (``masked=False``): the same learner with a plain categorical over the six
  rules and no mask in its input (the interface before action masks): its actions for
  robots without a choice are drawn, change nothing, and still get gradient.
- **Seeds.** ``seed`` seeds torch, the env and the training line seeds, drawn from the
  task's training seeds (never its evaluation seeds): runs are repeatable on one machine.

>>> result = train(PPOConfig(task="baseline", algo="ippo", total_steps=20_000))  # +SKIP
>>> result.policy.act(obs, mask)                                                  # +SKIP
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any, cast

import numpy as np
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.modules import MaskedCategorical, MultiAgentMLP, ProbabilisticActor
from torchrl.objectives import ClipPPOLoss
from torchrl.objectives.value.functional import generalized_advantage_estimate

from pnp_twin.learning.tasks import get_task, make_env
from pnp_twin.twin.errors import UserError

ALGOS = ("ippo", "mappo")
OBS, MASK, STATE = ("agents", "observation"), ("agents", "action_mask"), ("agents", "state")
ACTION, LOGP, LOGITS = ("agents", "action"), ("agents", "action_log_prob"), ("agents", "logits")
VALUE, ADV, TARGET = ("agents", "state_value"), ("agents", "advantage"), ("agents", "value_target")


class MarlError(UserError):
    """A bad training setting; the message is one line."""


@dataclass(frozen=True)
class PPOConfig:
    """One training run: the task, the algorithm and its budget (env steps, all lines)."""

    task: str = "baseline"
    algo: str = "ippo"
    """``ippo`` (decentralised critic) or ``mappo`` (centralised critic on the global state)."""
    masked: bool = True
    """Masked categorical policy (False: plain categorical, no mask in the input)."""
    skip_noops: bool = True
    """The env skips epochs where no deciding robot has a choice."""
    team_reward: bool = True
    """Every agent gets the team's reward (the sum over robots); False: its own."""
    rules: tuple[str, ...] = ("FIFO", "LIFO", "SIRO", "SD", "LD", "SPT")
    """The action set (all six rules; the envs' default is the paper's five)."""
    total_steps: int = 200_000
    """Env steps, all lines together (each step: every agent of one line)."""
    num_envs: int = 32
    rollout: int = 64
    """Env steps per line per update."""
    epochs: int = 4
    minibatches: int = 4
    lr: float = 3e-4
    gamma: float = 0.9
    """Discount per simulated second (a step of ``tau`` s: ``gamma ** tau``)."""
    lmbda: float = 0.95
    clip: float = 0.2
    entropy: float = 0.01
    hidden: int = 64
    reward_scale: float = 0.05
    """Rewards are multiplied by this for learning (eq. 1 is about 2 a pick)."""
    seed: int = 0
    duration: float | None = None
    """A shorter run than the task's (tests, the quick-start); None: the task's."""
    threads: int = 1
    """torch threads."""
    eval_every: int = 0
    """Env steps between evaluations of the greedy policy (0: none): ``eval_G`` in the log,
    at the first update at or past each multiple."""
    eval_seeds: int = 4
    """Evaluation runs per evaluation, on validation line seeds 500,000 + i (never the
    task's training or evaluation seeds)."""
    eval_duration: float = 120.0
    """Feeding time of an evaluation run, s (short: G at fixed intervals costs little)."""

    def check(self) -> None:
        if self.algo not in ALGOS:
            raise MarlError(f"algo: '{self.algo}' is not one of {', '.join(ALGOS)}")
        get_task(self.task)
        if int(self.eval_every) < 0 or int(self.eval_seeds) < 2 or self.eval_duration <= 10.0:
            raise MarlError("eval_every >= 0, eval_seeds >= 2 and eval_duration > 10 s, please")
        for name in ("total_steps", "num_envs", "rollout", "epochs", "minibatches", "hidden"):
            if int(getattr(self, name)) < 1:
                raise MarlError(f"{name}: give an integer >= 1")
        if not 0.0 < self.gamma <= 1.0 or not 0.0 <= self.lmbda <= 1.0:
            raise MarlError("gamma must be in (0, 1] and lmbda in [0, 1]")


@dataclass
class TrainResult:
    """A trained policy, its settings and its training log."""

    config: PPOConfig
    policy: AgentPolicy
    critic: TensorDictModule
    log: list[dict[str, float]] = field(default_factory=list)
    env_steps: int = 0
    sim_seconds: float = 0.0
    """Simulated seconds the lines ran during training (all lines)."""
    wall_s: float = 0.0
    cpu_s: float = 0.0

    def to_json(self) -> dict[str, Any]:
        return {
            "config": asdict(self.config),
            "env_steps": self.env_steps,
            "sim_seconds": self.sim_seconds,
            "wall_s": self.wall_s,
            "cpu_s": self.cpu_s,
            "log": self.log,
        }


class Features:
    """The agents' inputs from the env's arrays: window (flattened), id (one-hot), mask."""

    def __init__(self, env: Any, masked: bool) -> None:
        self.n = env.n_agents
        self.k = len(env.rules)
        self.masked = masked
        self.window_shape = tuple(int(x) for x in env.single_observation_space.shape)
        self.window = int(np.prod(self.window_shape))
        self.state_size = int(np.prod(env.state_space.shape))
        self.eye = torch.eye(self.n)
        self.obs_size = self.window + self.n + (self.k if masked else 0)
        self.critic_size = self.state_size + self.n

    def observation(self, obs: np.ndarray, mask: np.ndarray) -> torch.Tensor:
        """(lines, agents, obs_size) float32."""
        e = obs.shape[0]
        parts = [
            torch.from_numpy(obs.reshape(e, self.n, -1).astype(np.float32)),
            self.eye.expand(e, self.n, self.n),
        ]
        if self.masked:
            parts.append(torch.from_numpy(mask.astype(np.float32)))
        return torch.cat(parts, dim=-1)

    def state(self, state: np.ndarray) -> torch.Tensor:
        """(lines, agents, critic_size) float32: the whole belt and the agent's id."""
        e = state.shape[0]
        s = torch.from_numpy(state.reshape(e, 1, -1).astype(np.float32)).expand(e, self.n, -1)
        return torch.cat([s, self.eye.expand(e, self.n, self.n)], dim=-1)


def _mlp(features: Features, inputs: int, outputs: int, hidden: int) -> MultiAgentMLP:
    """The per-agent network of the actor and the critic: shared weights, two tanh layers."""
    return MultiAgentMLP(
        n_agent_inputs=inputs,
        n_agent_outputs=outputs,
        n_agents=features.n,
        centralized=False,
        share_params=True,
        depth=2,
        num_cells=hidden,
        activation_class=nn.Tanh,
    )


def _actor(features: Features, hidden: int) -> ProbabilisticActor:
    net = _mlp(features, features.obs_size, features.k, hidden)
    module = TensorDictModule(net, in_keys=[OBS], out_keys=[LOGITS])
    if features.masked:
        return ProbabilisticActor(
            module,
            in_keys={"logits": LOGITS, "mask": MASK},
            out_keys=[ACTION],
            distribution_class=MaskedCategorical,
            return_log_prob=True,
            log_prob_key=LOGP,
        )
    return ProbabilisticActor(
        module,
        in_keys={"logits": LOGITS},
        out_keys=[ACTION],
        distribution_class=torch.distributions.Categorical,
        return_log_prob=True,
        log_prob_key=LOGP,
    )


def _critic(features: Features, algo: str, hidden: int) -> TensorDictModule:
    central = algo == "mappo"
    net = _mlp(features, features.critic_size if central else features.obs_size, 1, hidden)
    return TensorDictModule(net, in_keys=[STATE if central else OBS], out_keys=[VALUE])


class AgentPolicy:
    """A trained actor as a function of the env's arrays: ``act(obs, mask)`` -> rule index
    per line and agent, (lines, agents) int64 (greedy: the most likely allowed rule)."""

    def __init__(self, actor: ProbabilisticActor, features: Features) -> None:
        self.actor = actor
        self.features = features

    @torch.no_grad()
    def logits(self, obs: np.ndarray, mask: np.ndarray) -> torch.Tensor:
        """The policy net's raw logits, (lines, agents, K), before any mask."""
        td = _td(self.features, obs, mask)
        return self.actor.module[0](td)[LOGITS]

    @torch.no_grad()
    def act(self, obs: np.ndarray, mask: np.ndarray, greedy: bool = True) -> np.ndarray:
        logits = self.logits(obs, mask)
        if self.features.masked:
            logits = logits.masked_fill(~torch.from_numpy(mask.astype(bool)), -torch.inf)
        if greedy:
            return logits.argmax(-1).numpy()
        return torch.distributions.Categorical(logits=logits).sample().numpy()


def _td(features: Features, obs: np.ndarray, mask: np.ndarray) -> TensorDict:
    e = obs.shape[0]
    agents = TensorDict(
        {"observation": features.observation(obs, mask),
         "action_mask": torch.from_numpy(mask.astype(bool))},
        batch_size=[e, features.n],
    )  # fmt: skip
    return TensorDict({"agents": agents}, batch_size=[e])


def _reset_lines(env: Any, rng: np.random.Generator, seeds: range, mask: np.ndarray) -> Any:
    """Reset the lines in ``mask`` to fresh training line seeds, one reset per line."""
    out = None
    for e in np.flatnonzero(mask).tolist():
        m = np.zeros(env.num_envs, dtype=bool)
        m[e] = True
        k = int(rng.integers(seeds.start, seeds.stop))
        out = env.reset(options={"line_seed": k, "reset_mask": m})
    return out


def train(
    config: PPOConfig, progress: Callable[[dict[str, float]], None] | None = None
) -> TrainResult:
    """Train ``config.algo`` on ``config.task`` for ``config.total_steps`` env steps."""
    config.check()
    torch.set_num_threads(config.threads)
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    task = get_task(config.task)
    extra = {} if config.duration is None else {"overrides": task.settings(config.duration)}
    env = make_env(
        task, "parallel_vector", num_envs=config.num_envs, skip_noops=config.skip_noops,
        team_reward=config.team_reward, rules=config.rules, **extra,
    )  # fmt: skip
    feats = Features(env, config.masked)
    actor, critic = _actor(feats, config.hidden), _critic(feats, config.algo, config.hidden)
    loss = ClipPPOLoss(
        actor, critic, clip_epsilon=config.clip, entropy_coeff=config.entropy,
        critic_coeff=0.5, loss_critic_type="l2", normalize_advantage=False,
    )  # fmt: skip
    loss.set_keys(
        action=ACTION, sample_log_prob=LOGP, value=VALUE, advantage=ADV, value_target=TARGET
    )
    optim = torch.optim.Adam(loss.parameters(), lr=config.lr)
    n, e, t_len = feats.n, config.num_envs, config.rollout
    central = config.algo == "mappo"

    start_wall, start_cpu = time.perf_counter(), time.process_time()
    env.reset(seed=config.seed)
    # numba's OpenMP layer sets OpenMP's thread count (to its own, every core) when it
    # first launches, which is in the env's first step of the process, and torch's CPU ops
    # then use it: set torch's threads again after that launch (two threads spinning on a
    # busy 2-core machine made training 7x slower per CPU second, measured).
    torch.set_num_threads(config.threads)
    obs, info = _reset_lines(env, rng, task.train_seeds, np.ones(e, dtype=bool))
    result = TrainResult(config, AgentPolicy(actor, feats), critic)
    iterations = max(1, config.total_steps // (e * t_len))
    next_eval = config.eval_every
    for it in range(iterations):
        steps: list[TensorDict] = []
        rewards = torch.zeros(t_len, e, n)
        taus = torch.zeros(t_len, e)
        dones = torch.zeros(t_len, e, dtype=torch.bool)
        grips: list[float] = []
        for t in range(t_len):
            td = _td(feats, obs, info["action_mask"])
            if central:
                td["agents", "state"] = feats.state(env.state())
            with torch.no_grad():
                actor(td)
            action = td["agents", "action"].numpy()
            obs, rew, term, trunc, info = env.step(action)
            steps.append(td)
            rewards[t] = torch.from_numpy(rew.astype(np.float32)) * config.reward_scale
            taus[t] = torch.from_numpy(info["tau"].astype(np.float32))
            ended = term | trunc
            dones[t] = torch.from_numpy(term.copy())
            result.sim_seconds += float(info["tau"].sum())
            if ended.any():
                grips.extend(info["gripping_rate"][ended].tolist())
                obs, info = _reset_lines(env, rng, task.train_seeds, ended)
        result.env_steps += e * t_len
        batch = cast(TensorDict, torch.stack(steps, dim=0))  # (T, lines)
        last = _td(feats, obs, info["action_mask"])
        if central:
            last["agents", "state"] = feats.state(env.state())
        with torch.no_grad():
            critic(batch)
            critic(last)
        value = batch["agents", "state_value"]  # (T, lines, agents, 1)
        nxt = torch.cat([value[1:], last["agents", "state_value"][None]], dim=0)
        done = dones[:, :, None, None].expand(t_len, e, n, 1)
        gamma = (config.gamma**taus)[:, :, None, None].expand(t_len, e, n, 1)
        adv, target = generalized_advantage_estimate(
            gamma,  # type: ignore[arg-type]  # a per-step discount: gamma ** tau
            config.lmbda,
            value,
            nxt,
            rewards[..., None],
            done,
            done,
            time_dim=0,
        )
        batch["agents", "advantage"] = (adv - adv.mean()) / (adv.std() + 1e-8)
        batch["agents", "value_target"] = target
        flat = batch.reshape(-1)
        size = flat.shape[0] // config.minibatches
        stats: dict[str, float] = {}
        for _ in range(config.epochs):
            order = torch.randperm(flat.shape[0])
            for b in range(config.minibatches):
                sub = flat[order[b * size : (b + 1) * size]]
                parts = loss(sub)
                total = parts["loss_objective"] + parts["loss_critic"] + parts["loss_entropy"]
                optim.zero_grad()
                total.backward()
                nn.utils.clip_grad_norm_(loss.parameters(), 1.0)
                optim.step()
                stats = {k: float(v.detach()) for k, v in parts.items() if v.numel() == 1}
        row = {
            "iteration": float(it + 1),
            "env_steps": float(result.env_steps),
            "reward_per_s": float(
                rewards.sum() / config.reward_scale / max(float(taus.sum()), 1e-9)
            ),
            "episodes": float(len(grips)),
            "train_G": float(np.mean(grips)) if grips else float("nan"),
            **stats,
        }
        if config.eval_every and (result.env_steps >= next_eval or it == iterations - 1):
            row.update(evaluate_now(config, result.policy))
            while next_eval <= result.env_steps:
                next_eval += config.eval_every
        row["wall_s"] = time.perf_counter() - start_wall
        result.log.append(row)
        if progress is not None:
            progress(row)
    result.wall_s = time.perf_counter() - start_wall
    result.cpu_s = time.process_time() - start_cpu
    env.close()
    return result


VALIDATION_SEED = 500_000
"""First validation line seed (evaluations during training)."""


def evaluate_now(config: PPOConfig, policy: AgentPolicy) -> dict[str, float]:
    """The greedy policy's mean G (95 % t-interval) on ``config.eval_seeds`` validation runs of
    ``config.eval_duration`` s (torch's RNG untouched, so training goes on as it would)."""
    from pnp_twin.learning.marl_eval import rates
    from pnp_twin.twin.stats import t_interval

    seeds = range(VALIDATION_SEED, VALIDATION_SEED + config.eval_seeds)
    g = rates(config.task, policy.act, list(seeds), duration=config.eval_duration,
              rules=config.rules, skip_noops=config.skip_noops)  # fmt: skip
    torch.set_num_threads(config.threads)
    mean, low, high = t_interval(g, 0.95)
    return {"eval_G": mean, "eval_G_low": low, "eval_G_high": high}


__all__ = ["ALGOS", "AgentPolicy", "MarlError", "PPOConfig", "TrainResult", "train"]
