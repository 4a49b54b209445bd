"""Trajectory uncertainty by posterior function samples (paper Sec. III-C, "RFF sampling").

``ensemble``: sampled models, sampled rollouts, coverage and calibration tables.
"""
