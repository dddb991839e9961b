"""The compiled vector environment's engine: many lines in hold mode stepped in one call.

:mod:`.batch` (:class:`~pnp_twin.learning.vector.batch.LineBatch`) holds the lines' arrays;
:mod:`.step` is the compiled step over the core's kernel (:mod:`pnp_twin.twin.fast.kernel`):
the epoch driver's option bookkeeping, the paper's reward, the episode's ends, the action
masks, skipped forced NooPs and the camera image. It lives on the learning floor, not in
the core: the core simulates, this folder turns a simulation into an environment. Its
compiled code is cached under a fingerprint of the engine's folder and of this one
(:mod:`pnp_twin.twin.fast.jit`), so a change here recompiles it.
"""
