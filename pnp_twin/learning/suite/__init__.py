"""The task suite's versioned task files: one TOML per task and version, read by
:mod:`pnp_twin.learning.tasks`."""
