"""Trained HDQN models shipped with pnp-twin (package data, not code).

Each folder is one training run (``model.safetensors``, ``meta.json`` and its evaluation
tables). Name one like a scenario: ``--policy hdqn:paper_baseline__async_rollout`` finds
``pnp_twin/models/paper_baseline__async_rollout`` when no such folder exists where you are.
"""
