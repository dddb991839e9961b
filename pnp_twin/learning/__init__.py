"""Learning over the twin: the Gymnasium / PettingZoo environments (:mod:`.envs`), HDQN
training (``train``, ``dqn_update``, ``replay``, ``train_checkpoint``, ``rollout``,
``rollout_train``), evaluation and run logs.

Training modules need the ``learn`` extra (torch); import the submodules you need.
"""
