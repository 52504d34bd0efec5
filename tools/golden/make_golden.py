#!/usr/bin/env python3
"""Writes golden trajectories of the CommonRoad single-track model for the `sim` crate's tests.

Uses the real `commonroad-vehicle-models` package (vehicle_dynamics_st with parameter set
vehicle2, BMW 320i) and integrates it with classic fixed-step RK4 at 0.01 s, the integrator and
step the Rust model uses. Inputs (steering velocity, longitudinal acceleration) are held constant
over each step. Run `tools/golden/run.sh` to (re)create st_vehicle2.json.
"""
import json
import math
import sys

from vehiclemodels.parameters_vehicle2 import parameters_vehicle2
from vehiclemodels.vehicle_dynamics_st import vehicle_dynamics_st

DT = 0.01


def rk4(x, u, p, dt):
    def f(s):
        return vehicle_dynamics_st(s, u, p)

    k1 = f(x)
    k2 = f([xi + dt / 2 * ki for xi, ki in zip(x, k1)])
    k3 = f([xi + dt / 2 * ki for xi, ki in zip(x, k2)])
    k4 = f([xi + dt * ki for xi, ki in zip(x, k3)])
    return [xi + dt / 6 * (a + 2 * b + 2 * c + d) for xi, a, b, c, d in zip(x, k1, k2, k3, k4)]


def case(name, x0, seconds, inputs, dt=DT):
    """inputs(t) -> [steering velocity, acceleration] at the start of the step."""
    p = parameters_vehicle2()
    steps = int(round(seconds / dt))
    stride = max(1, int(round(0.01 / dt)))
    x = list(x0)
    # Inputs as change points [step, u1, u2]; states after every `stride` steps.
    changes, states = [], [list(x)]
    for k in range(steps):
        u = list(inputs(k * dt))
        if not changes or changes[-1][1:] != u:
            changes.append([k] + u)
        x = rk4(x, u, p, dt)
        if (k + 1) % stride == 0:
            states.append(list(x))
    return {"name": name, "dt": dt, "steps": steps, "stride": stride, "x0": list(x0), "input_changes": changes,
            "states": states}


def st0(v=0.0, delta=0.0, psi=0.0):
    # [sx, sy, delta, v, psi, psi_dot, beta] as in vehiclemodels.init_st
    return [0.0, 0.0, delta, v, psi, 0.0, 0.0]


def main():
    p = parameters_vehicle2()
    cases = [
        # From rest: kinematic branch below 0.1 m/s, then the dynamic one, then the power limit
        # above v_switch = 7.319 m/s.
        case("straight_acceleration", st0(), 5.0, lambda t: [0.0, 3.0]),
        case("braking", st0(v=20.0), 2.0, lambda t: [0.0, -8.0]),
        # Steering velocity 0.4 rad/s (the limit) for 0.5 s, then hold 0.2 rad.
        case("step_steer", st0(v=15.0), 4.0, lambda t: [0.4 if t < 0.5 else 0.0, 0.0]),
        case("slalom", st0(v=12.0), 6.0, lambda t: [0.4 * math.sin(math.pi * t), 0.5]),
        # Crosses |v| = 0.1 m/s downwards and back up while steering: the model switch. The ST
        # branch is stiff near the switch (eigenvalues about -216/v 1/s for vehicle2), so this
        # case uses a 0.2 ms step. (Reverse driving is not exercised.)
        case("low_speed_switch", st0(v=0.3, delta=0.05), 2.0, lambda t: [0.2, -0.3 if t < 0.9 else 0.5], dt=0.0002),
        # Requests beyond the limits are clipped by the constraints.
        case("saturated_inputs", st0(v=5.0), 3.0, lambda t: [2.0 if t < 1.5 else -2.0, 20.0]),
    ]
    out = {
        "source": "commonroad-vehicle-models vehicle_dynamics_st, parameters_vehicle2",
        "integrator": "rk4 (classic, fixed step per case; inputs held over each step)",
        "params": {
            "a": p.a, "b": p.b, "m": p.m, "I_z": p.I_z, "h_s": p.h_s,
            "mu": p.tire.p_dy1, "C_S": -p.tire.p_ky1 / p.tire.p_dy1,
            "steering": {"min": p.steering.min, "max": p.steering.max, "v_min": p.steering.v_min, "v_max": p.steering.v_max},
            "longitudinal": {"a_max": p.longitudinal.a_max, "v_min": p.longitudinal.v_min,
                             "v_max": p.longitudinal.v_max, "v_switch": p.longitudinal.v_switch},
        },
        "cases": cases,
    }
    json.dump(out, sys.stdout, indent=None)


if __name__ == "__main__":
    main()
