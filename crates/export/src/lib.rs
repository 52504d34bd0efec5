//! `export`: writers of standard formats that other tools open, so a carla-gs corner case can be
//! replayed outside carla-gs, and readers of the same files for round-trip tests.
//!
//! * [`xosc`]: OpenSCENARIO 1.2 (`.xosc`) for one executed corner case: the ego, the adversary and
//!   optionally every other logged actor follow timed world-frame trajectories
//!   (`docs/export.md`).
//! * [`xodr`]: OpenDRIVE road networks from a scene's lanes and road edges (or a flat road
//!   covering a scene without lanes), which the OpenSCENARIO file can reference and the CARLA
//!   bridge loads.
//! * [`ground`]: the logged actors' ground-contact heights, shared by the writers and the bridge.
//!
//! Depends on `scene` only: it exports what the stages wrote, whoever wrote it.

pub mod error;
pub mod ground;
pub mod xml;
pub mod xodr;
pub mod xosc;

pub use error::ExportError;
pub use xodr::{build_road_network, read_xodr, write_xodr, write_xodr_file, RoadNetwork, XodrOptions};
pub use xosc::{read_xosc, write_xosc, write_xosc_file, XoscCase, XoscEntity, XoscOptions, XoscVersion, XoscVertex};
