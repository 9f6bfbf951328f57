"""Optimal servo references (paper Sec. V): MVN (30) and minimum time (31).

Pure: numpy/scipy/OSQP/Clarabel only. Angles in degrees, speeds in deg/s, time in s.
"""
