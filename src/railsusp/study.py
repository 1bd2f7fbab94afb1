"""Published numbers of the reference study (C80 / K6, CNN-GRU + NSGA-II), for comparison.

Source: *Suspension Parameter Estimation Method for Heavy-Duty Freight Trains Based on Deep
Learning* (the study in ``shared/reference``). Forces in kN. The study does not say which
statistic of the force records its tables give, nor which wheel; railsusp compares with
several statistics and says which one it uses.
"""

from __future__ import annotations

#: Table 8: nominal SIMPACK model vs instrumented wheelset, before calibration.
#: condition -> (lateral simulated, lateral measured, vertical simulated, vertical measured)
TABLE8_BEFORE: dict[str, tuple[float, float, float, float]] = {
    "straight": (12.48, 11.42, 140.20, 138.91),
    "curve": (31.52, 29.67, 131.28, 128.12),
    "uphill": (13.24, 11.21, 140.95, 138.17),
}

#: Table 9: after calibration, same layout.
TABLE9_AFTER: dict[str, tuple[float, float, float, float]] = {
    "straight": (12.22, 11.42, 140.54, 138.91),
    "curve": (31.01, 29.67, 130.71, 128.12),
    "uphill": (12.38, 11.21, 139.34, 138.17),
}

#: Table 5: key parameters, initial and estimated values (display units of railsusp.params).
TABLE5_ESTIMATE: dict[str, tuple[float, float]] = {
    "X13": (14.0, 16.1),
    "X14": (10.0, 8.3),
    "X15": (170.0, 164.0),
    "X16": (1.8, 1.7),
    "X17": (1.8, 1.91),
    "X18": (50.0, 51.3),
}

#: Table 7: surrogate accuracy, model -> (vertical sim, predicted, rel. error %,
#: lateral sim, predicted, rel. error %).
TABLE7_SURROGATES: dict[str, tuple[float, float, float, float, float, float]] = {
    "RBF": (126.13, 123.86, 1.80, 20.3, 22.35, 10.09),
    "CNN-LSTM": (126.13, 123.91, 1.76, 20.3, 21.73, 7.04),
    "CNN-BiLSTM": (126.13, 128.38, 1.78, 20.3, 21.24, 4.63),
    "BP": (126.13, 129.04, 2.30, 20.3, 18.97, 6.55),
    "CNN-GRU": (126.13, 128.13, 1.56, 20.3, 19.57, 3.59),
}

#: Sobol screening result of the study (its Figure 2 and Section 2.2).
KEY_LATERAL = ("X14", "X15", "X16", "X18")
KEY_VERTICAL = ("X13", "X15", "X17")
