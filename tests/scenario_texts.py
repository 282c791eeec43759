"""Scenario file texts shared by the tests."""

#: A complete, valid scenario file; tests derive malformed ones from it by replacing one piece.
VALID = """
name = "case"
expected_attractor = "stick-slip"

[model]
M = 1.0
kappa = 1.0

[initial]
x = 0.0
v = 0.1

[kinetic]
law = "coulomb"
F0 = 0.5

[static]
law = "constant"
F0 = 1.0

[inputs.v_drive]
constant = 0.1

[simulation]
stop_time = 10.0
output_interval = 0.1

[tolerance]
max_abs_dx = 1e-9
max_abs_dv = 1e-9
event_time = 1e-9
"""
