"""The paper's figures and the experiment settings it fixes: one place for every constant.

The numbers are copied from the paper's text and tables: distance errors in cm, times in ms,
per-joint variances in deg^2. :data:`RADII`, :data:`DIVERSITY_TARGETS` and :data:`SWEEP_TARGET`
are the targets its experiments use; :data:`NAMES`, :data:`VARIANTS` and :data:`LETTERS` are how
the report and its figures name methods, variants and targets.
"""

from typing import Dict, Tuple

#: Radii of the per-radius table, around the base origin [m] (paper: 5 to 90 cm).
RADII: Tuple[float, ...] = tuple(round(0.05 * k, 2) for k in range(1, 19))
#: The paper's four targets of "Distance error in different postures" (a to d) [m].
DIVERSITY_TARGETS = ((0.1357, -0.321, 0.222), (-0.333, 0.246, 0.1999),
                     (-0.188, -0.168, 0.321), (0.2020, 0.2021, 0.2022))
#: Target of the paper's element sweep (Table 5) [m].
SWEEP_TARGET = (-0.25, -0.25, 0.25)
#: The paper's figures (cm, ms, deg^2), copied from its text and tables.
PAPER: Dict = {
    'workspace_cm': {'sik': 0.5, 'psik': 1.7, 'fcn': 45.0, 'fcn_uni': 40.0, 'anfis': 70.0},
    'radius_cm': {
        'sik': (1.84, 1.87, 0.42, 0.44, 0.73, 0.47, 0.71, 0.63, 0.58, 0.68, 0.64, 0.64, 0.84,
                0.65, 0.73, 0.83, 1.15, 0.88),
        'psik': (1.31, 2.16, 1.22, 1.21, 2.36, 1.15, 1.35, 1.34, 1.31, 1.78, 1.90, 1.61, 1.6,
                 2.18, 2.16, 1.86, 2.45, 2.11),
        'anfis': (91.1, 88.6, 88.2, 85.8, 82.2, 82.5, 75.9, 76.5, 74.7, 70.1, 70.3, 71.3, 68.3,
                  66.2, 66.5, 62.9, 60.5, 68.4),
        'fcn': (26.2, 23.9, 28.6, 27.4, 29.0, 29.9, 30.5, 37.1, 40.6, 35.3, 41.8, 50.9, 59.5,
                56.4, 66.2, 70.0, 76.3, 80.0),
        'fcn_uni': (18.6, 18.8, 18.6, 19.2, 22.2, 22.8, 26.4, 32.1, 31.3, 40.1, 40.6, 41.7,
                    57.9, 59.6, 67.9, 66.5, 76.9, 80.5),
    },
    'radius_avg_cm': {'sik': 0.82, 'psik': 1.73, 'anfis': 75.0, 'fcn': 45.0, 'fcn_uni': 41.2},
    'time_ms': {'sik': 4.0, 'psik': 4.0, 'fcn': 3.0, 'anfis': 0.15},
    'variance_deg2': {
        'sik': ((141.23, 70.59, 175.55, 5.75, 178.47, 54.69, 133.93),
                (194.92, 56.36, 188.62, 15.60, 213.78, 147.51, 114.54),
                (166.66, 99.60, 176.19, 2.99, 142.76, 109.93, 51.89),
                (110.25, 57.55, 255.89, 1.25, 335.27, 131.81, 126.34)),
        'psik': ((138.53, 70.26, 176.80, 5.69, 179.89, 54.97, 0.01),
                 (205.18, 56.01, 159.10, 17.50, 249.05, 121.48, 71.94),
                 (164.97, 98.49, 178.18, 3.03, 142.63, 109.57, 0.01),
                 (172.87, 55.37, 249.41, 1.28, 341.17, 131.19, 1.50)),
    },
    'diversity_cm': {
        'sik': ((0.22, 0.25, 0.54, 0.22, 0.31, 1.6, 0.29, 0.56, 0.19, 0.61),
                (0.35, 0.25, 0.48, 0.4, 0.36, 0.38, 0.42, 0.4, 0.34, 0.35),
                (0.74, 0.24, 1.04, 0.57, 0.40, 0.63, 0.43, 0.45, 0.31, 0.61),
                (0.21, 0.29, 0.31, 0.47, 1.08, 0.30, 0.46, 0.40, 0.46, 0.71)),
        'psik': ((0.98, 0.65, 1.03, 0.82, 1.70, 1.28, 3.24, 0.63, 1.20, 2.72),
                 (0.93, 1.51, 1.46, 2.44, 1.32, 0.40, 0.74, 1.48, 1.13, 1.83),
                 (0.94, 1.45, 3.35, 1.26, 0.51, 1.64, 0.77, 1.09, 0.29, 0.63),
                 (1.03, 0.27, 1.04, 2.18, 2.05, 1.31, 1.18, 1.39, 2.94, 1.17)),
    },
    'sweep_cm': ((0.08, 0.24, 0.6, 0.81, 0.65, 0.51), (0.06, 0.15, 0.18, 0.08, 0.49, 0.6),
                 (0.03, 0.58, 0.66, 0.38, 0.37, 0.38), (0.03, 0.11, 0.18, 0.19, 0.42, 0.86)),
    'orientation': {'distance_cm': 1.35, 'cosine': 0.9983},
}

#: The methods as the paper names them.
NAMES = {'sik': 'SIK', 'psik': 'PSIK', 'fcn': 'FCN', 'fcn_uni': 'FCN-uni', 'anfis': 'ANFIS'}
#: The report's names of the distance-error variants (see :func:`sik_ros.eval.studies.sik_errors`).
VARIANTS = {'lookup': 'look-up (paper\'s protocol)', 'raw_first': 'raw best (product)',
            'raw_mean': 'raw mean of 10 (product)', 'refined': 'refined (product)', 'raw': 'raw'}
#: The paper's labels of the targets of one experiment (a to d).
LETTERS = 'abcd'
