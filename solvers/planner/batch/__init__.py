"""Many independent planning problems at once (thesis §3.5.2 planner, one call per vector env).

* :mod:`.planning` -- :func:`plan_batch` and :func:`start_batch_workers`, the entry points;
* :mod:`.pool` -- the helper processes and whether sharing pays (caller side);
* :mod:`.server` -- what a helper process runs;
* :mod:`.claims` -- the page of claims through which the problems are shared.
"""

from __future__ import annotations

from solvers.planner.batch.planning import plan_batch, start_batch_workers
from solvers.planner.batch.pool import shutdown_pool

__all__ = ["plan_batch", "shutdown_pool", "start_batch_workers"]
