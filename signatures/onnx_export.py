"""Export fitted scikit-learn pipelines to ONNX (training side; needs skl2onnx).

ONNX is the shipped format: a data-only protobuf (no code runs on load, unlike
pickle/joblib), evaluated by onnxruntime in tens of microseconds per return,
without importing scikit-learn. The opset is pinned so rebuilds are byte-identical.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

TARGET_OPSET = 17
ML_OPSET = 3


def sklearn_to_onnx(model: object, n_features: int, path: Path) -> None:
    """Write `model` (a classifier Pipeline) as ONNX with outputs `label` and `probabilities`."""
    from skl2onnx import convert_sklearn
    from skl2onnx.common.data_types import FloatTensorType

    _reset_name_counters()
    final = model.steps[-1][1] if hasattr(model, "steps") else model
    with warnings.catch_warnings():  # SVC probA_/probB_ deprecation (see classifiers._fit)
        warnings.filterwarnings("ignore", category=FutureWarning)
        onx = convert_sklearn(
            model, name=type(final).__name__, initial_types=[("X", FloatTensorType([None, n_features]))],
            options={id(final): {"zipmap": False}}, target_opset={"": TARGET_OPSET, "ai.onnx.ml": ML_OPSET})
    onx.doc_string = ""
    path.write_bytes(onx.SerializeToString(deterministic=True))


def _reset_name_counters() -> None:
    """skl2onnx numbers some node names with process-global counters: restart them so the
    same model always serialises to the same bytes, whatever was converted before."""
    from skl2onnx.common import _topology, utils

    _topology.Variable._UNIQUE_NUMBER_ = 0
    utils._unique_index["subgraph"] = 0


def check_export(model: object, path: Path, X: np.ndarray, atol: float = 1e-4) -> float:
    """Largest |p_sklearn - p_onnx| over X (guards the export; kNN ties may differ by one vote)."""
    import onnxruntime as ort

    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    p_onnx = sess.run(["probabilities"], {"X": X.astype(np.float32)})[0]
    return float(np.max(np.abs(model.predict_proba(X.astype(np.float32)) - p_onnx)))
