"""The paper's evaluation on real data: clutter sensitivity, W on broken maps, W as confidence,
walls, break detection in sessions and the cleaning benchmark.

``run_evaluation(EvaluationConfig.small(), out_dir)`` writes ``report.md``, CSV tables and PNG figures;
``python -m rose_logs.evaluation OUT_DIR --config full`` runs the benchmark configuration.
"""

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
