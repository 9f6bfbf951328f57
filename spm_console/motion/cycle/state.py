"""What the cycles of one run share (:class:`LoopState`), made by the executor at the start of
a run and handed to each cycle. Degrees and seconds."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.servo.estimation import FiniteDifference, KalmanVelocity, ModelPredictor
from spm_console.motion.safety import SafetyMonitor

F = NDArray[np.float64]


@dataclass
class LoopState:
    """What the cycles of one run share: filters, predictors, the safety monitor, the last
    good position and the reference held since the last write."""

    safety: SafetyMonitor
    kf: KalmanVelocity
    fd: FiniteDifference
    pred: ModelPredictor
    pred_t: ModelPredictor
    last_good: F
    t_state: float
    u_prev: F
