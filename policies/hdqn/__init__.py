"""The hierarchical DQN: the meta-controller that picks a dispatching rule per robot.

Inference only: ``network`` (Q-network presets), ``agent`` (the online network and its greedy
action), ``numpy_forward`` (the same network's forward pass in numpy, for decisions),
``checkpoint`` (reading safetensors + JSON), ``features`` (the decision features a student
of the lookahead controller sees besides the image), ``policy`` (the trained policy used like any
other, :class:`pnp_twin.policies.hdqn.policy.HDQNPolicy`, ``--policy hdqn:DIR``). Training
(target network, optimizer, semi-MDP update, replay, writing checkpoints) lives in
:mod:`pnp_twin.learning` (``dqn_update``, ``replay``, ``train_checkpoint``, ``train``).
Everything here needs torch (the ``learn`` extra); import the submodules you need.
"""

MODES = ("single", "sync", "async")
"""Training set-ups: one joint agent; multi-agent t_all; hierarchical multi-agent t_continue."""

TERMINATION = {"single": "t_continue", "sync": "t_all", "async": "t_continue"}
"""The termination scheme each mode trains under."""
