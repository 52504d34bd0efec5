//! One model drawn view after view on the host (a video on the CPU): what `view::draw` does,
//! without redoing for every view the work that does not change between views.
//!
//! `view::draw` composes the whole scene for each view: it copies every background Gaussian into a
//! fresh world set, rotates every actor's SH coefficients into the world, and allocates the
//! rasterizer's buffers anew. Between the views of a video only the actors move, and most of them
//! not at all (parked cars) or not between a frame's cameras. A video of PandaSet 002 at a quarter
//! of the size spent a quarter of its time there (perf, 2026-11-28: SH rotation 12 %, copying 11 %,
//! allocation about 6 %). Here the background's rows stay at the front of one world set, each
//! actor's world rows are kept with the pose they were built for and rebuilt only when it
//! changes, and while the same actors are in view only the ones that moved are rewritten in
//! place (on 002 the actors hold more Gaussians than the background: copying all of them for
//! every view was the next tenth of the time). The rasterizer's context is reused.
//!
//! The world set holds the same rows in the same order as `compose_into` builds, so every image is
//! bit for bit `view::draw`'s (`tests/host_drawer.rs`). A drawer belongs to one model: the caller
//! (`painter::Painter`) keeps it beside that model.

use crate::backend::Backend;
use crate::compose::{actor_pose, push_actor, push_background, Layers};
use crate::model::SceneModel;
use crate::pose::BoxPose;
use crate::view::{drawn, Drawn};
use scene::Scene;
use splat::render::Image;
use splat::Gaussians;

/// The kept world set, the actors' rows and the rasterizer's context.
pub struct HostDrawer<C> {
    world: Gaussians,
    /// How many background rows lead `world` (`None`: it starts with the actors).
    background: Option<usize>,
    /// The actors in `world` after the background, in order: (actor, pose, first row).
    placed: Vec<(usize, BoxPose, usize)>,
    /// Per actor, the pose its world rows were last built for, and those rows.
    actors: Vec<Option<(BoxPose, Gaussians)>>,
    ctx: C,
}

impl<C: Default> Default for HostDrawer<C> {
    fn default() -> Self {
        HostDrawer {
            world: Gaussians::empty(0),
            background: None,
            placed: Vec::new(),
            actors: Vec::new(),
            ctx: C::default(),
        }
    }
}

/// An actor's world rows at `pose` (`g`: its Gaussians) from the cache `slot`, built there when the pose changed.
fn rows_at<'a>(
    slot: &'a mut Option<(BoxPose, Gaussians)>,
    g: &Gaussians,
    pose: &BoxPose,
    degree: usize,
) -> &'a Gaussians {
    if slot.as_ref().is_some_and(|(p, _)| p != pose) {
        *slot = None;
    }
    &slot
        .get_or_insert_with(|| {
            let mut rows = Gaussians::empty(degree);
            push_actor(g, pose, degree, &mut rows);
            (*pose, rows)
        })
        .1
}

impl<C> HostDrawer<C> {
    /// `view::draw` of `model` (the drawer's model, every time) from `cam` at time `t`.
    #[allow(clippy::too_many_arguments)]
    pub fn draw<B: Backend<Context = C>>(
        &mut self,
        backend: &B,
        model: &SceneModel,
        scene: &Scene,
        cam: &splat::Camera,
        t: f64,
        layers: Layers,
        poses: &dyn Fn(usize) -> Option<Option<BoxPose>>,
    ) -> Drawn {
        let degree = model.background.sh_degree;
        let with_background = layers != Layers::ActorsOnly;
        let alive: Vec<(usize, BoxPose)> = if layers == Layers::BackgroundOnly {
            vec![]
        } else {
            (0..model.actors.len())
                .filter_map(|ai| poses(ai).unwrap_or_else(|| actor_pose(model, scene, ai, t)).map(|p| (ai, p)))
                .collect()
        };
        self.actors.resize_with(model.actors.len(), || None);
        // The same background and the same actors in the same order: only the actors that moved
        // are rewritten, in place; else the actors are laid out again after the background.
        let same = self.background.is_some() == with_background
            && alive.len() == self.placed.len()
            && alive.iter().zip(&self.placed).all(|(a, p)| a.0 == p.0);
        if same {
            for ((ai, pose), placed) in alive.iter().zip(&mut self.placed) {
                if placed.1 != *pose {
                    let rows = rows_at(&mut self.actors[*ai], &model.actors[*ai].gaussians, pose, degree);
                    overwrite(&mut self.world, placed.2, rows);
                    placed.1 = *pose;
                }
            }
        } else {
            self.keep_background(model, with_background, degree);
            self.placed.clear();
            for (ai, pose) in alive {
                let rows = rows_at(&mut self.actors[ai], &model.actors[ai].gaussians, &pose, degree);
                self.placed.push((ai, pose, self.world.len()));
                append(&mut self.world, rows);
            }
        }
        let mut img = Image::default();
        backend.render(&self.world, cam, &model.render_options(), &mut img, &mut self.ctx);
        drawn(model, cam, layers, img)
    }

    /// Leaves `world` holding the background's rows alone (`with`) or nothing.
    fn keep_background(&mut self, model: &SceneModel, with: bool, degree: usize) {
        let w = &mut self.world;
        match (with, self.background) {
            (true, Some(n)) => truncate(w, n),
            (true, None) => {
                truncate(w, 0);
                w.sh_degree = degree;
                push_background(&model.background, degree, w);
                self.background = Some(model.background.len());
            }
            (false, _) => {
                truncate(w, 0);
                w.sh_degree = degree;
                self.background = None;
            }
        }
    }
}

/// Keeps the first `n` rows of `w`.
fn truncate(w: &mut Gaussians, n: usize) {
    let k = w.coeffs() * 3;
    w.means.truncate(n);
    w.log_scales.truncate(n);
    w.rotations.truncate(n);
    w.opacity_logits.truncate(n);
    w.sh.truncate(n * k);
}

/// Writes `rows` (same SH degree) over the rows of `w` from `start` on.
fn overwrite(w: &mut Gaussians, start: usize, rows: &Gaussians) {
    let (n, k) = (rows.len(), rows.coeffs() * 3);
    w.means[start..start + n].copy_from_slice(&rows.means);
    w.log_scales[start..start + n].copy_from_slice(&rows.log_scales);
    w.rotations[start..start + n].copy_from_slice(&rows.rotations);
    w.opacity_logits[start..start + n].copy_from_slice(&rows.opacity_logits);
    w.sh[start * k..(start + n) * k].copy_from_slice(&rows.sh);
}

/// Appends `rows` (same SH degree) to `w`.
fn append(w: &mut Gaussians, rows: &Gaussians) {
    w.means.extend_from_slice(&rows.means);
    w.log_scales.extend_from_slice(&rows.log_scales);
    w.rotations.extend_from_slice(&rows.rotations);
    w.opacity_logits.extend_from_slice(&rows.opacity_logits);
    w.sh.extend_from_slice(&rows.sh);
}
