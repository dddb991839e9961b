"""The hierarchical DQN: the meta-controller that picks a dispatching rule per robot.

Modules: ``network`` (Q-network presets), ``replay`` (ring buffer), ``agent`` (the DQN and
its semi-MDP update), ``checkpoint`` (safetensors + JSON), ``train`` (a training run, top to
bottom), ``evaluate`` (paired comparison with the rules). The trained policy used like any
other is :class:`policies.hdqn.policy.HDQNPolicy` (``--policy hdqn:DIR``). Everything here
needs torch (the ``learn`` extra); import the submodules you need.
"""

MODES = ("single", "sync", "async")
"""Training set-ups: one joint agent; multi-agent t_all; hierarchical multi-agent t_continue."""

TERMINATION = {"single": "t_continue", "sync": "t_all", "async": "t_continue"}
"""The termination scheme each mode trains under."""
