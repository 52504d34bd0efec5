//! Training settings: one documented TOML file (`docs/recon.md` lists every key), every key
//! optional with the defaults below, unknown keys refused with their path. The defaults follow
//! 3DGS / Street Gaussians (learning rates, densification rules, SH schedule) with iteration counts
//! shortened for the CPU; the geometry weights are the paper's 0.1 each.

use crate::loss::LossWeights;
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrainConfig {
    pub seed: u64,
    pub iterations: usize,
    /// Fraction of the image size to train at (intrinsics scale with it).
    pub scale: f64,
    /// Every `held_out_every`-th frame (frame index % n == 0) of every camera is held out.
    pub held_out_every: usize,
    /// Final SH degree; the active degree grows by one every `sh_degree_interval` iterations.
    pub sh_degree: usize,
    pub sh_degree_interval: usize,
    /// Save a checkpoint every this many iterations (0: only at the end)...
    pub checkpoint_interval: usize,
    /// ...once at least this many seconds of training have passed since the last one (0: at
    /// every interval). A checkpoint holds the whole state (1.1 GB at 760k Gaussians; about a
    /// second to write, and on the device a download first), so a fixed interval alone cost a
    /// large run a fifth of its time; the result does not depend on when checkpoints are taken.
    pub checkpoint_min_seconds: f64,
    /// Mip-Splatting's 2D filter: the screen-space low-pass (0.3 px^2) with its opacity
    /// compensation (`splat::project`, antialiased), in training and wherever the model is drawn,
    /// so a Gaussian drawn smaller or larger on screen than in training keeps its energy.
    pub antialiased: bool,
    /// Mip-Splatting's 3D smoothing filter (`smoothing`): each Gaussian is convolved with an
    /// isotropic Gaussian of variance `filter_3d` times the square of the finest pixel footprint
    /// any training view saw it with (Mip-Splatting: 0.2), so no Gaussian is finer than the
    /// training images could tell, and a car drawn closer than the log saw it stays whole instead
    /// of breaking into needles. 0: off. Baked into the saved model.
    pub filter_3d: f64,
    /// The 3D filter on the actors alone: a corner case brings a vehicle closer than the log saw
    /// it, while the street is seen from the log's own path; the background keeps its detail.
    pub filter_3d_actors_only: bool,
    /// Vehicles (cars, vans, trucks, buses) are drawn with their mirror image about the box's long
    /// vertical plane (y -> -y in the box frame): a side the log saw stands in for the side it did
    /// not. Pedestrians and cyclists are not mirrored. Baked into the saved model.
    pub mirror_vehicles: bool,
    /// Place the actors at each image's own capture time rather than its frame's (`View::time`):
    /// a PandaSet image is taken 39 to 61 ms before its frame, and a car at 10 m/s moves half a
    /// metre meanwhile. Training, its filter, its start's colours and `eval-recon` all follow it.
    pub actors_at_image_time: bool,
    /// Pixels left out of training to measure how vehicle models hold up (`protocol`).
    pub protocol: crate::protocol::Protocol,
    pub lr: LearningRates,
    pub loss: LossWeights,
    pub densify: DensifyConfig,
    pub init: InitConfig,
    /// Sky cube-map face resolution (texels).
    pub sky_res: usize,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LearningRates {
    /// Mean learning rate at the start and the end (times the scene extent), exponential decay.
    pub means: f64,
    pub means_final: f64,
    pub log_scales: f64,
    pub rotations: f64,
    pub opacity: f64,
    pub sh_dc: f64,
    pub sh_rest: f64,
    pub sky: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DensifyConfig {
    /// Density control runs from `from x iterations` to `until x iterations` (3DGS: 500 and
    /// 15000 of 30000), so a short CPU run keeps 3DGS's proportions.
    pub from: f64,
    pub until: f64,
    pub interval: usize,
    /// Average screen-space (NDC) gradient above which a Gaussian is cloned or split.
    pub grad_threshold: f64,
    /// Split (rather than clone) when the largest scale exceeds this fraction of the scene extent.
    pub percent_dense: f64,
    /// Opacities are reset every `opacity_reset_every x iterations` (3DGS: 3000 of 30000).
    pub opacity_reset_every: f64,
    /// Whether the opacity reset also caps the actors' opacities (off by default). A vehicle
    /// that passes the ego is in a tenth of the training views or fewer, so it gets a tenth of
    /// the steps the background gets: between resets it cannot regain its opacity (on PandaSet
    /// 002 at 1,500 iterations every actor ended below 0.07 mean opacity, half-transparent
    /// ghosts). The reset exists to clear floaters; an actor's Gaussians are held inside its
    /// box by the box rule, so they have no free space to float in.
    pub reset_actors: bool,
    /// An actor's Gaussian is pruned when its `actor_sigma`-sigma ellipsoid reaches out of the
    /// actor's box padded by 10 % along any box axis (0: only its centre must stay inside). A
    /// Gaussian centred in the box may otherwise be metres wide and paint the road beside the
    /// car, or its shadow, as the car (on PandaSet 002 that was up to two thirds of a distant
    /// car's rendered silhouette).
    pub actor_sigma: f64,
    /// Whether the box rule keeps pruning the actors after `until`, every `interval` iterations,
    /// when nothing else is cloned, split or pruned: Gaussians keep moving and growing to the end.
    pub contain_to_end: bool,
    /// Whether every density step also prunes the background's Gaussians inside the space the
    /// tracked objects take up at some time of the log (`actor_space`), so the static background
    /// cannot stand in for a moving car.
    pub clear_actor_space: bool,
    pub prune_opacity: f64,
    /// After the first opacity reset: prune Gaussians wider than this on screen (pixels; 0: off,
    /// the default, because a street camera sees kerbs, parked cars and walls a metre or two away,
    /// whose Gaussians are legitimately wide on screen)...
    pub max_screen_size: f64,
    /// ...or larger than this fraction of the scene extent in the world.
    pub max_world_fraction: f64,
    /// No clone or split beyond this many Gaussians in all (the CPU budget).
    pub max_gaussians: usize,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InitConfig {
    /// Background points: voxel size (m) for LiDAR / depth points, and a cap.
    pub voxel_m: f64,
    pub max_points: usize,
    /// Random points when the scene has neither LiDAR nor depth.
    pub random_points: usize,
    /// Points per actor (from LiDAR inside the box, topped up with random points in the box).
    pub actor_points: usize,
    pub opacity: f64,
    /// The actors' starting opacity (0: `opacity`). A vehicle's surface the training views never
    /// show keeps its start: at 0.1 a car's unseen side stays see-through; a car is opaque.
    pub actor_opacity: f64,
    /// Colour an actor's LiDAR point only from a view that sees it (its depth within a tolerance of
    /// the depth prior there; `init::visible`), and give the points no view sees the actor's body
    /// colour (the median of its seen points) instead of dropping them.
    pub actor_visibility: bool,
    /// Stride (pixels at training scale) when back-projecting depth priors.
    pub depth_stride: usize,
    /// Surface-aligned start (`surface.rs`): neighbours per point for the local PCA (0: every
    /// Gaussian starts isotropic, as in 3DGS), the planarity test (smallest variance at most this
    /// times the middle one) and the start's thickness (normal-axis scale / in-plane scale).
    pub surface_neighbours: usize,
    pub surface_planarity: f64,
    pub surface_thickness: f64,
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig {
            seed: 0,
            iterations: 3000,
            scale: 0.5,
            held_out_every: 8,
            sh_degree: 3,
            sh_degree_interval: 1000,
            checkpoint_interval: 500,
            checkpoint_min_seconds: 300.0,
            antialiased: false,
            filter_3d: 0.0,
            filter_3d_actors_only: false,
            mirror_vehicles: false,
            actors_at_image_time: false,
            protocol: crate::protocol::Protocol::None,
            lr: LearningRates::default(),
            loss: LossWeights::default(),
            densify: DensifyConfig::default(),
            init: InitConfig::default(),
            sky_res: 32,
        }
    }
}

impl Default for LearningRates {
    fn default() -> Self {
        LearningRates {
            means: 1.6e-4,
            means_final: 1.6e-6,
            log_scales: 5e-3,
            rotations: 1e-3,
            opacity: 2.5e-2,
            sh_dc: 2.5e-3,
            sh_rest: 2.5e-3 / 20.0,
            sky: 1e-2,
        }
    }
}

impl Default for DensifyConfig {
    fn default() -> Self {
        DensifyConfig {
            from: 0.02,
            until: 0.5,
            interval: 100,
            grad_threshold: 2e-4,
            percent_dense: 0.01,
            opacity_reset_every: 0.1,
            reset_actors: false,
            actor_sigma: 1.0,
            contain_to_end: true,
            clear_actor_space: true,
            prune_opacity: 0.005,
            max_screen_size: 0.0,
            max_world_fraction: 0.1,
            max_gaussians: 200_000,
        }
    }
}

impl Default for InitConfig {
    fn default() -> Self {
        InitConfig {
            voxel_m: 0.15,
            max_points: 60_000,
            random_points: 30_000,
            actor_points: 3000,
            opacity: 0.1,
            actor_opacity: 0.0,
            actor_visibility: false,
            depth_stride: 4,
            surface_neighbours: 16,
            surface_planarity: 0.1,
            surface_thickness: 0.2,
        }
    }
}

impl TrainConfig {
    /// Parses a TOML config; the error names the key.
    pub fn from_toml(text: &str) -> Result<TrainConfig, String> {
        let cfg: TrainConfig = toml::from_str(text).map_err(|e| e.to_string())?;
        cfg.validate()?;
        Ok(cfg)
    }

    pub fn validate(&self) -> Result<(), String> {
        if !(self.scale > 0.0 && self.scale <= 1.0) {
            return Err(format!("scale must be in (0, 1], got {}", self.scale));
        }
        let i = &self.init;
        if !(i.surface_thickness > 0.0 && i.surface_thickness <= 1.0 && i.surface_planarity >= 0.0) {
            return Err(format!(
                "init.surface_thickness must be in (0, 1] and init.surface_planarity >= 0, got {} and {}",
                i.surface_thickness, i.surface_planarity
            ));
        }
        if !(self.checkpoint_min_seconds.is_finite() && self.checkpoint_min_seconds >= 0.0) {
            let v = self.checkpoint_min_seconds;
            return Err(format!("checkpoint_min_seconds must be a finite number >= 0, got {v}"));
        }
        if self.sh_degree > 3 {
            return Err(format!("sh_degree must be 0..=3, got {}", self.sh_degree));
        }
        if self.held_out_every == 1 {
            return Err("held_out_every = 1 would hold out every view (0 disables the split)".into());
        }
        if self.densify.interval == 0 || self.sh_degree_interval == 0 {
            return Err("densify.interval and sh_degree_interval must be positive".into());
        }
        let d = &self.densify;
        if !(0.0..=1.0).contains(&d.from)
            || !(0.0..=1.0).contains(&d.until)
            || !(0.0..=1.0).contains(&d.opacity_reset_every)
        {
            return Err(
                "densify.from, densify.until and densify.opacity_reset_every are fractions of the iterations (0 to 1)"
                    .into(),
            );
        }
        if !(self.filter_3d.is_finite() && (0.0..=10.0).contains(&self.filter_3d)) {
            return Err(format!(
                "filter_3d must be a finite number in [0, 10] (pixels^2; Mip-Splatting: 0.2), got {}",
                self.filter_3d
            ));
        }
        crate::budget::sizes(self)?;
        crate::budget::rates_and_weights(self)
    }

    /// Sets each view's actor time (`View::time`) to the clock these settings place actors on.
    pub fn set_actor_clock(&self, views: &mut [crate::data::View]) {
        if self.actors_at_image_time {
            views.iter_mut().for_each(|v| v.time = v.image_time);
        }
    }

    /// The densification window and opacity-reset period in iterations.
    pub fn densify_schedule(&self) -> (usize, usize, usize) {
        let at = |f: f64| (f * self.iterations as f64).round() as usize;
        (at(self.densify.from), at(self.densify.until), at(self.densify.opacity_reset_every))
    }

    /// The SH degree drawn at iteration `it` (0-based).
    pub fn active_degree(&self, it: usize) -> usize {
        (it / self.sh_degree_interval).min(self.sh_degree)
    }

    /// The SH degree a model trained with these settings stores: the highest the schedule draws
    /// within `iterations` (`sh_degree` when it gets there). Bands it never draws would stay zero,
    /// add nothing to a colour and cost memory and optimiser bandwidth on every step (at 1,500
    /// iterations and the default interval: degree 1, 12 coefficients a Gaussian instead of 48).
    pub fn stored_degree(&self) -> usize {
        self.active_degree(self.iterations.saturating_sub(1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_model_stores_the_degrees_the_schedule_draws() {
        let mut cfg = TrainConfig::default();
        assert_eq!((cfg.iterations, cfg.sh_degree_interval, cfg.sh_degree), (3000, 1000, 3));
        assert_eq!(cfg.stored_degree(), 2, "the last step, 2999, draws degree 2");
        for (iterations, degree) in [(0, 0), (1, 0), (1000, 0), (1001, 1), (1500, 1), (3001, 3), (30_000, 3)] {
            cfg.iterations = iterations;
            assert_eq!(cfg.stored_degree(), degree, "{iterations} iterations");
            assert!((0..iterations).all(|it| cfg.active_degree(it) <= degree), "{iterations}: a drawn band is stored");
        }
        cfg.sh_degree = 1;
        assert_eq!(cfg.stored_degree(), 1);
    }

    #[test]
    fn toml_round_trip_and_unknown_keys() {
        let cfg = TrainConfig::default();
        let text = toml::to_string(&cfg).unwrap();
        assert_eq!(TrainConfig::from_toml(&text).unwrap(), cfg);
        let partial = TrainConfig::from_toml("iterations = 10\n[loss]\nnormal = 0.0\n").unwrap();
        assert_eq!(partial.iterations, 10);
        assert_eq!(partial.loss.normal, 0.0);
        assert_eq!(partial.loss.flat, 0.1);
        let err = TrainConfig::from_toml("[loss]\nnormals = 1\n").unwrap_err();
        assert!(err.contains("normals"), "{err}");
        assert!(TrainConfig::from_toml("scale = 2.0").unwrap_err().contains("scale"));
    }

    #[test]
    fn out_of_range_values_are_refused_naming_the_key() {
        for (text, key) in [
            ("sky_res = 100000", "`sky_res` must be in 1..=512"),
            ("iterations = 0", "`iterations`"),
            ("[lr]\nmeans = nan", "`lr.means` must be a finite number"),
            ("[lr]\nopacity = inf", "`lr.opacity`"),
            ("[loss]\nssim = -5", "`loss.ssim` must be a finite number in [0, 1], got -5"),
            ("[loss]\nssim = 2.0", "`loss.ssim` must be a finite number in [0, 1], got 2"),
            ("[loss]\ndepth = 101", "`loss.depth` must be a finite number in [0, 100], got 101"),
            ("[densify]\nactor_sigma = nan", "`densify.actor_sigma` must be a finite number in [0, 100], got NaN"),
            ("[densify]\nactor_sigma = -1", "`densify.actor_sigma` must be a finite number in [0, 100], got -1"),
            ("[densify]\nmax_gaussians = 1000000000", "`densify.max_gaussians`"),
            ("[init]\nopacity = 1.5", "`init.opacity`"),
            ("checkpoint_min_seconds = -1", "checkpoint_min_seconds must be a finite number >= 0, got -1"),
            ("checkpoint_min_seconds = nan", "checkpoint_min_seconds"),
            ("filter_3d = -0.2", "filter_3d must be a finite number in [0, 10]"),
            ("filter_3d = nan", "filter_3d"),
            ("protocol = \"closeup\"", "protocol"),
        ] {
            let e = TrainConfig::from_toml(text).unwrap_err();
            assert!(e.contains(key), "{text}: {e}");
        }
        for entry in std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/../../configs")).unwrap() {
            let text = std::fs::read_to_string(entry.unwrap().path()).unwrap();
            TrainConfig::from_toml(&text).unwrap();
        }
    }
}
