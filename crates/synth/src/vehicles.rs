//! The other road users: vehicle specs (size, colour, body style) and constant-velocity
//! trajectories along the lanes, one per kind of motion the behaviour library needs: a lead
//! vehicle in the ego's lane, same-direction traffic in the adjacent lane, oncoming traffic and
//! cars parked at both kerbs. Also the ego's own trajectory and the tracks for `scene.json`.

use crate::street::{LANES_Y, PARKING_Y};
use glam::DVec3;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use scene::{ObjectClass, Track, TrackState};

/// The ego's lane (right-hand lane, driving +x) and its start.
pub const EGO_LANE_Y: f64 = LANES_Y[0];
/// Seconds between frames (10 Hz).
pub const FRAME_DT: f64 = 0.1;

/// How a vehicle moves relative to the ego.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    /// Ahead of the ego in its lane, same direction, not faster.
    Lead,
    /// Behind the ego in its lane, same direction, slowly closing.
    Follow,
    /// Same direction in the adjacent lane.
    Adjacent,
    /// Opposite direction.
    Oncoming,
    /// Standing at a kerb.
    Parked,
}

impl Motion {
    pub fn as_str(self) -> &'static str {
        match self {
            Motion::Lead => "lead",
            Motion::Follow => "follow",
            Motion::Adjacent => "adjacent",
            Motion::Oncoming => "oncoming",
            Motion::Parked => "parked",
        }
    }
}

/// Body style: where the cabin sits and how big the wheels are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    /// Hood in front, cabin in the middle.
    Sedan,
    /// Short hood, cabin over most of the length (vans, SUVs).
    Van,
    /// Cab in front, cargo box behind.
    Truck,
}

/// One vehicle: a box of `size_lwh` (the tracked box: every part lies inside it) moving with
/// constant velocity `speed` along its heading from `start` (box centre at t = 0).
#[derive(Clone, Debug)]
pub struct Vehicle {
    pub track_id: String,
    pub motion: Motion,
    pub style: Style,
    pub size_lwh: [f64; 3],
    pub colour: [f32; 3],
    pub start: DVec3,
    pub heading: f64,
    pub speed: f64,
}

impl Vehicle {
    /// Box centre at time `t` (s).
    pub fn centre_at(&self, t: f64) -> DVec3 {
        self.start + self.velocity() * t
    }

    pub fn velocity(&self) -> DVec3 {
        DVec3::new(self.heading.cos(), self.heading.sin(), 0.0) * self.speed
    }
}

/// The ego's speed (m/s) and start position (its origin, on the ground).
#[derive(Clone, Copy, Debug)]
pub struct EgoMotion {
    pub start: DVec3,
    pub speed: f64,
}

impl EgoMotion {
    pub fn position_at(&self, t: f64) -> DVec3 {
        self.start + DVec3::X * self.speed * t
    }
}

const COLOURS: [[f32; 3]; 10] = [
    [0.75, 0.08, 0.08], // red
    [0.10, 0.22, 0.55], // blue
    [0.88, 0.88, 0.86], // white
    [0.12, 0.12, 0.13], // black
    [0.55, 0.57, 0.60], // silver
    [0.90, 0.70, 0.10], // yellow
    [0.15, 0.40, 0.22], // green
    [0.35, 0.20, 0.12], // brown
    [0.95, 0.45, 0.10], // orange
    [0.40, 0.55, 0.75], // light blue
];

fn spec(rng: &mut ChaCha8Rng, allow_truck: bool) -> (Style, [f64; 3]) {
    let roll = rng.random_range(0..10);
    let j = |rng: &mut ChaCha8Rng, v: f64| v * rng.random_range(0.95..1.05);
    match roll {
        0..=5 => (Style::Sedan, [j(rng, 4.5), j(rng, 1.85), j(rng, 1.48)]),
        6..=8 => (Style::Van, [j(rng, 4.9), j(rng, 1.95), j(rng, 1.85)]),
        _ if allow_truck => (Style::Truck, [j(rng, 7.5), j(rng, 2.4), j(rng, 3.0)]),
        _ => (Style::Van, [j(rng, 5.2), j(rng, 2.0), j(rng, 2.1)]),
    }
}

/// Places the vehicles for a sequence of `duration_s` seconds (ego as given). Fixed roles,
/// seeded positions, speeds, styles and colours; at least one of every `Motion`.
pub fn generate(rng: &mut ChaCha8Rng, ego: &EgoMotion, duration_s: f64) -> Vec<Vehicle> {
    let ego_x = ego.start.x;
    let end_x = ego.position_at(duration_s).x;
    // (motion, lane y, heading, x at t = 0, speed)
    let mut roles: Vec<(Motion, f64, f64, f64, f64)> = vec![
        (Motion::Lead, EGO_LANE_Y, 0.0, ego_x + rng.random_range(22.0..28.0), ego.speed * rng.random_range(0.8..0.9)),
        // 12-16 m behind (centres), closing at most 0.3 m/s: never touches the ego in 10 s.
        (
            Motion::Follow,
            EGO_LANE_Y,
            0.0,
            ego_x - rng.random_range(12.0..16.0),
            ego.speed * rng.random_range(1.0..1.03),
        ),
        (
            Motion::Adjacent,
            LANES_Y[1],
            0.0,
            ego_x - rng.random_range(4.0..8.0),
            ego.speed * rng.random_range(1.2..1.35),
        ),
        (
            Motion::Adjacent,
            LANES_Y[1],
            0.0,
            ego_x + rng.random_range(40.0..50.0),
            ego.speed * rng.random_range(0.85..1.0),
        ),
        (
            Motion::Oncoming,
            LANES_Y[2],
            std::f64::consts::PI,
            ego_x + rng.random_range(110.0..130.0),
            rng.random_range(9.0..11.0),
        ),
        (
            Motion::Oncoming,
            LANES_Y[3],
            std::f64::consts::PI,
            ego_x + rng.random_range(60.0..75.0),
            rng.random_range(7.0..9.0),
        ),
        (
            Motion::Oncoming,
            LANES_Y[2],
            std::f64::consts::PI,
            ego_x + rng.random_range(190.0..210.0),
            rng.random_range(9.0..11.0),
        ),
    ];
    // Parked cars along both kerbs, spread over the whole drive.
    let mut x = ego_x + rng.random_range(28.0..36.0);
    let mut left = false;
    while x < end_x + 60.0 && roles.len() < 14 {
        let (y, heading) = if left { (PARKING_Y, std::f64::consts::PI) } else { (-PARKING_Y, 0.0) };
        roles.push((Motion::Parked, y, heading, x, 0.0));
        left = !left;
        x += rng.random_range(14.0..30.0);
    }
    roles
        .into_iter()
        .enumerate()
        .map(|(i, (motion, y, heading, x0, speed))| {
            let (style, size_lwh) = spec(rng, motion != Motion::Lead);
            let colour = COLOURS[rng.random_range(0..COLOURS.len())];
            Vehicle {
                track_id: format!("{}-{}", motion.as_str(), i + 1),
                motion,
                style,
                size_lwh,
                colour,
                start: DVec3::new(x0, y, size_lwh[2] / 2.0),
                heading,
                speed,
            }
        })
        .collect()
}

/// One track per vehicle with a state at every frame (velocity included).
pub fn tracks(vehicles: &[Vehicle], frames: usize) -> Vec<Track> {
    vehicles
        .iter()
        .map(|v| Track {
            id: v.track_id.clone(),
            class: ObjectClass::Vehicle,
            states: (0..frames)
                .map(|f| TrackState {
                    frame: f,
                    center: v.centre_at(f as f64 * FRAME_DT),
                    heading: v.heading,
                    size_lwh: v.size_lwh,
                    velocity: Some(v.velocity()),
                    valid: true,
                    motion: None,
                })
                .collect(),
        })
        .collect()
}
