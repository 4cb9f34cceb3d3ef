"""The learned leg detector's model file (``vipsm/data/legs_model.npz``, written by ``tools/train_legs.py``)
read for the estimator, which does no I/O itself (:func:`vipsm.legs.model_from_arrays` checks it), and the
leg-candidate segments of a scan outside the estimator (training and checks; the labelled legs of a
recording: :func:`app.evaluation.real_data.labelled_leg_rows`)."""

from __future__ import annotations

import functools
from importlib import resources
from pathlib import Path

import numpy as np

from vipsm.bodies import BodiesConfig, segments
from vipsm.legs import LegConfig, LegModel, ModelError, model_from_arrays, segment_features
from vipsm.prefilter import PrefilterConfig, veiling_masks


def default_model_path() -> Path:
    return Path(str(resources.files("vipsm") / "data" / "legs_model.npz"))


def load_leg_model(path: str | Path | None = None) -> LegModel:
    """The forest stored at ``path`` (default: the packaged model), read without pickle;
    :class:`vipsm.legs.ModelError` when the file is missing or unusable."""
    path = Path(path) if path is not None else default_model_path()
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, ValueError) as exc:
        raise ModelError(f"cannot read the leg model {path}: {exc}") from exc
    return model_from_arrays(arrays, f"the leg model {path}")


@functools.lru_cache(maxsize=1)
def default_leg_model() -> LegModel:
    """The packaged model, read once per process (it is immutable)."""
    return load_leg_model()


def leg_candidates(r: np.ndarray, b: np.ndarray) -> tuple[list[tuple[int, int, np.ndarray]], np.ndarray]:
    """The leg-candidate segments of one scan (start, stop, points) and their features, pre-filtered and
    segmented as the estimator does."""
    mixed, lone = veiling_masks(r, b, PrefilterConfig())
    dropped = mixed | lone
    rr = np.where(dropped, np.nan, r)
    return segment_features(rr, b, segments(rr, b, BodiesConfig(), dropped), LegConfig())
