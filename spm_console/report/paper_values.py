"""Numbers printed in the paper, as data (degrees, unit vectors, seconds).

Source: "Numerical Optimal Control of a Spherical Parallel Manipulator Based on
Unique Kinematic Solutions" (Sec. VI). Matrices are given with v1..v3 as rows.
"""

from __future__ import annotations

import numpy as np

EQ32_THETA_DEG = (95.0, 110.0, 105.0)
EQ32_W = np.array([[-0.9962, -0.0503, -0.0712], [0.2989, 0.9125, -0.2793], [0.6123, -0.7618, -0.2114]])
EQ32_PRECISION = 1e-4  # printed to 4 decimals; two entries are one unit off in the last digit

EQ34_V = np.array([[-0.0817, 0.8230, 0.5621], [0.9039, -0.1768, 0.3896], [-0.4204, -0.5401, 0.7291]])
EQ34_N = np.array([0.2321, 0.0613, 0.9708])
EQ34_PRECISION = 3.5e-4  # the paper prints eq. (34) from a loose solver tolerance (±3e-4)

TABLE1_THETA_DEG = (108.0, 60.0, 105.0)
TABLE1_V = np.array(
    [[-0.276580, 0.127085, 0.952551], [0.546672, -0.794538, 0.264311], [-0.790536, -0.593566, -0.150771]]
)
TABLE1_PRECISION = 5e-4  # the paper: solvers differ by up to 2e-4; Table I holds to ±5e-4

TABLE2_THETA_DEG = (0.0, 0.0, 0.0)
# Table II (trust-region row) in the paper's frame and leg numbering.
TABLE2_V_PAPER = np.array(
    [[-0.707080, -0.500016, 0.500016], [-0.079491, 0.862360, 0.500016], [0.786571, -0.362339, 0.500016]]
)
TABLE2_PRECISION = 5e-5


def table2_in_our_convention() -> np.ndarray:
    """Paper → ours: reflect y → −y and swap legs 2 and 3."""
    return TABLE2_V_PAPER[[0, 2, 1]] * np.array([1.0, -1.0, 1.0])


EQ35_A = np.array([[0.5481, 0.0435], [-45.1937, 3.3534]])
EQ35_B = np.array([0.4519, 45.1937])

MVN_START_DEG = (127.53, 83.23, 85.25)
MVN_GOAL_DEG = (66.80, 155.00, 131.48)
MVN_STEPS = 150
MVN_SECONDS = 25.0  # CVX, define + solve, MacBook Pro 2.9 GHz i7

MINTIME_START_DEG = (70.0, 90.0, 80.0)
MINTIME_GOAL_DEG = MVN_GOAL_DEG
MINTIME_VMAX_DEGPS = 50.0
MINTIME_N = 76
MINTIME_QPS = 8
MINTIME_SECONDS = 85.0
MINTIME_INITIAL_N = 100

REGION_HALFSPACES = 61
P_SERVO = 32.22
TS_S = 0.02
