//! Golden tests: our single-track model against the real `commonroad-vehicle-models` package.
//! `tools/golden/run.sh` integrated CommonRoad's `vehicle_dynamics_st` (vehicle2) with RK4 at a
//! fixed step; we integrate `sim::model::derivative` with the same RK4, step and inputs and
//! require every state component to agree to 1e-6 relative (floor 1: absolute for |x| < 1).

use serde::Deserialize;
use sim::model::{rk4_step, State};
use sim::params::VehicleParams;

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

#[test]
fn single_track_matches_commonroad() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/st_vehicle2.json");
    let golden: Golden = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let p = VehicleParams::vehicle2();
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
            while change + 1 < case.input_changes.len() && case.input_changes[change + 1].0 <= k {
                change += 1;
            }
            let (_, u1, u2) = case.input_changes[change];
            x = rk4_step(&x, [u1, u2], &p, case.dt);
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
