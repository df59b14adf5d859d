"""The paper's evaluation on real data: clutter sensitivity, W on broken maps, W as confidence,
walls, break detection in sessions and the cleaning benchmark.

``run_evaluation(EvaluationConfig.small(), out_dir)`` writes ``report.md``, CSV tables and PNG figures;
``python -m rose_logs.evaluation OUT_DIR --config full`` runs the benchmark configuration.
"""

from __future__ import annotations

import pkgutil
from typing import TYPE_CHECKING

from rose.lazy import lazy_exports

if TYPE_CHECKING:
    from rose_logs.evaluation.clutter import ClutteredMap, add_clutter
    from rose_logs.evaluation.config import EvaluationConfig
    from rose_logs.evaluation.report import EvaluationReport, run_evaluation

__all__ = [
    "ClutteredMap",
    "EvaluationConfig",
    "EvaluationReport",
    "add_clutter",
    "run_evaluation",
]

# Loaded on first use: ``rose-bag``'s parser needs only the configuration, and the report's modules
# load scipy and the whole of ROSE (a third of a second).
__getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "ClutteredMap": "rose_logs.evaluation.clutter",
        "add_clutter": "rose_logs.evaluation.clutter",
        "EvaluationConfig": "rose_logs.evaluation.config",
        "EvaluationReport": "rose_logs.evaluation.report",
        "run_evaluation": "rose_logs.evaluation.report",
    },
    __all__,
    # ``rose_logs.evaluation.report`` after a plain ``import rose_logs.evaluation``, as before.
    tuple(module.name for module in pkgutil.iter_modules(__path__)),
)
