//! Golden tests: our single-track model against the real `commonroad-vehicle-models` package.
//! `tools/golden/run.sh` integrated CommonRoad's `vehicle_dynamics_st` (vehicle2) with RK4 at a
//! fixed step; we integrate `sim::model::derivative` with the same RK4, step and inputs and
//! require every state component to agree to 1e-6 relative (floor 1: absolute for |x| < 1).
//! CommonRoad's tyres are linear and unbounded: the parity test uses `vehicle2_linear`. The
//! default, friction-limited model must agree with the package too while every axle force stays
//! in the linear range (below the saturation knee), and must stay below `friction * g` after.

use serde::Deserialize;
use sim::model::{acceleration_constraints, axle_forces, derivative, rk4_step, State};
use sim::params::VehicleParams;
use sim::tyre::TyreModel;

#[derive(Deserialize)]
struct Case {
    name: String,
    dt: f64,
    steps: usize,
    stride: usize,
    x0: Vec<f64>,
    input_changes: Vec<(usize, f64, f64)>,
    states: Vec<Vec<f64>>,
}

#[derive(Deserialize)]
struct Golden {
    params: serde_json::Value,
    cases: Vec<Case>,
}

fn golden() -> Golden {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/st_vehicle2.json");
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn input_at(case: &Case, k: usize, change: &mut usize) -> [f64; 2] {
    while *change + 1 < case.input_changes.len() && case.input_changes[*change + 1].0 <= k {
        *change += 1;
    }
    let (_, u1, u2) = case.input_changes[*change];
    [u1, u2]
}

#[test]
fn single_track_matches_commonroad() {
    let golden = golden();
    let p = VehicleParams::vehicle2_linear();
    // Our defaults are the package's vehicle2 numbers.
    let gp = &golden.params;
    for (ours, name) in
        [(p.a, "a"), (p.b, "b"), (p.m, "m"), (p.i_z, "I_z"), (p.h_s, "h_s"), (p.mu, "mu"), (p.c_sf, "C_S")]
    {
        assert!((ours - gp[name].as_f64().unwrap()).abs() < 1e-12, "{name}");
    }
    assert_eq!(p.longitudinal.v_switch, gp["longitudinal"]["v_switch"].as_f64().unwrap());
    assert_eq!(p.steering.v_max, gp["steering"]["v_max"].as_f64().unwrap());
    assert_eq!(golden.cases.len(), 6);
    for case in &golden.cases {
        let mut x: State = case.x0.clone().try_into().unwrap();
        let mut worst: f64 = 0.0;
        let mut change = 0;
        for k in 0..case.steps {
            x = rk4_step(&x, input_at(case, k, &mut change), &p, case.dt);
            if (k + 1) % case.stride == 0 {
                let g = &case.states[(k + 1) / case.stride];
                for (i, (a, b)) in x.iter().zip(g).enumerate() {
                    let rel = (a - b).abs() / b.abs().max(1.0);
                    assert!(rel < 1e-6, "{}: step {} state {i}: ours {a}, CommonRoad {b}", case.name, k + 1);
                    worst = worst.max(rel);
                }
            }
        }
        println!("{:<22} {:>6} steps of {:.4} s: worst relative error {worst:.2e}", case.name, case.steps, case.dt);
    }
}

#[test]
fn friction_limited_model_matches_commonroad_in_the_linear_range() {
    let golden = golden();
    let p = VehicleParams::vehicle2();
    let TyreModel::FrictionCircle { linear_fraction, .. } = p.tyre else { panic!("default tyres are limited") };
    let mut linear_steps = 0;
    for case in &golden.cases {
        let mut x: State = case.x0.clone().try_into().unwrap();
        let mut change = 0;
        let mut linear = true;
        let mut compared = 0;
        let mut max_a_lat: f64 = 0.0;
        for k in 0..case.steps {
            let u = input_at(case, k, &mut change);
            // Linear range: both axles below the knee at the start of the step.
            if x[3].abs() >= p.kinematic_below {
                let u1 = acceleration_constraints(x[3], u[1], &p.longitudinal);
                linear &= axle_forces(&x, u1, &p).iter().all(|f| f.demand.abs() < 0.95 * linear_fraction * f.capacity);
            }
            x = rk4_step(&x, u, &p, case.dt);
            if x[3].abs() >= p.kinematic_below {
                let d = derivative(&x, u, &p);
                max_a_lat = max_a_lat.max((x[3] * (d[4] + d[6])).abs());
            }
            if linear && (k + 1) % case.stride == 0 {
                let g = &case.states[(k + 1) / case.stride];
                for (i, (a, b)) in x.iter().zip(g).enumerate() {
                    let rel = (a - b).abs() / b.abs().max(1.0);
                    assert!(rel < 1e-6, "{}: step {} state {i}: ours {a}, CommonRoad {b}", case.name, k + 1);
                }
                compared += 1;
            }
        }
        assert!(max_a_lat <= p.friction * 9.81 + 1e-9, "{}: |a_lat| reached {max_a_lat}", case.name);
        println!(
            "{:<22} linear range for {compared} of {} samples, max |a_lat| {max_a_lat:.2} m/s^2",
            case.name,
            case.states.len() - 1
        );
        if compared == case.states.len() - 1 {
            linear_steps += 1;
        }
    }
    // Straight acceleration and braking never leave the linear range: full parity there.
    assert!(linear_steps >= 2, "only {linear_steps} cases stayed linear throughout");
}
