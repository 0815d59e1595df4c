"""Estimators (KF, EKF, UKF, particle filter, CQKF), dynamics models, metrics and the generic filter node."""
