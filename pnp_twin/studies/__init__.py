"""Studies: sweeps with replications, sizing answers and the rule-mix search.

A study is a grid over scenario fields x policies x replications (common random numbers),
run on a local process pool or Ray, journaled run by run so it resumes after an interrupt,
and written to a folder in the format of ``docs/study_format.md``.
"""

from pnp_twin.studies.plan import RunSpec, StudyError, StudyPlan, build_plan
from pnp_twin.studies.runner import Options, run_sweep

__all__ = ["Options", "RunSpec", "StudyError", "StudyPlan", "build_plan", "run_sweep"]
