//! Generated prost types for our minimal Waymo schema (`proto/waymo_minimal.proto`).
#![allow(clippy::all, missing_docs)]
include!(concat!(env!("OUT_DIR"), "/waymo.open_dataset.rs"));
