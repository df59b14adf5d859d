"""The paper's evaluation on real data: clutter sensitivity, W on broken maps, W as confidence,
walls, break detection in sessions and the cleaning benchmark.

``run_evaluation(EvaluationConfig.small(), out_dir)`` writes ``report.md``, CSV tables and PNG figures;
``python -m rose_logs.evaluation OUT_DIR --config full`` runs the benchmark configuration.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

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

#: Where each public name lives. Loaded on first use: ``rose-bag``'s parser needs only the
#: configuration, and the report's modules load scipy and the whole of ROSE (a third of a second).
_HOMES = {
    "ClutteredMap": "clutter",
    "add_clutter": "clutter",
    "EvaluationConfig": "config",
    "EvaluationReport": "report",
    "run_evaluation": "report",
}


def __getattr__(name: str) -> Any:
    if name not in _HOMES:
        msg = f"module {__name__!r} has no attribute {name!r}"
        raise AttributeError(msg)
    return getattr(importlib.import_module(f"{__name__}.{_HOMES[name]}"), name)


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
