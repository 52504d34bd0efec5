//! Video layouts: which views make up one frame and where they go.
//! * `single:<CAMERA>`: one camera of the corner case.
//! * `front3`: the three front cameras side by side (FRONT_LEFT | FRONT | FRONT_RIGHT, or PandaSet's
//!   front_left_camera | front_camera | front_right_camera), like the paper's figure; cameras the
//!   scene lacks are left out, the middle one is required.
//! * `compare:<CAMERA>`: the logged original | the corner case | a bird's-eye panel (square, the
//!   views' height) with the ego, the adversary, its paths and the target zone. The panel sits
//!   beside the views rather than over them so that at small sizes it hides nothing.

use crate::RenderError;
use scene::Scene;

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Layout {
    Single { camera: String },
    FrontTriple,
    Compare { camera: String },
}

/// One tile of a frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Tile {
    /// A camera view, with (`true`) or without the corner-case motion.
    View {
        camera: String,
        corner_case: bool,
    },
    Bev,
}

/// The order of the front cameras in `front3`, per dataset's naming (Waymo, PandaSet).
pub const FRONT_THREE: [[&str; 3]; 2] =
    [["FRONT_LEFT", "FRONT", "FRONT_RIGHT"], ["front_left_camera", "front_camera", "front_right_camera"]];

impl std::str::FromStr for Layout {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.split_once(':') {
            None if s == "front3" => Ok(Layout::FrontTriple),
            Some(("single", c)) if !c.is_empty() => Ok(Layout::Single { camera: c.into() }),
            Some(("compare", c)) if !c.is_empty() => Ok(Layout::Compare { camera: c.into() }),
            _ => Err(format!("unknown layout `{s}` (one of single:<CAMERA>, front3, compare:<CAMERA>)")),
        }
    }
}

impl Layout {
    /// A short name for file names: `single-FRONT`, `front3`, `compare-FRONT`.
    pub fn slug(&self) -> String {
        match self {
            Layout::Single { camera } => format!("single-{camera}"),
            Layout::FrontTriple => "front3".into(),
            Layout::Compare { camera } => format!("compare-{camera}"),
        }
    }

    /// The tiles left to right, checked against the scene's cameras.
    pub fn tiles(&self, scene: &Scene) -> Result<Vec<Tile>, RenderError> {
        let need = |camera: &str| -> Result<String, RenderError> {
            scene.camera(camera).map(|c| c.name.clone()).ok_or_else(|| RenderError::NoCamera {
                camera: camera.into(),
                available: scene.cameras.iter().map(|c| c.name.as_str()).collect::<Vec<_>>().join(", "),
            })
        };
        Ok(match self {
            Layout::Single { camera } => vec![Tile::View { camera: need(camera)?, corner_case: true }],
            Layout::FrontTriple => {
                let three =
                    FRONT_THREE.iter().find(|t| scene.camera(t[1]).is_some()).ok_or_else(|| RenderError::NoCamera {
                        camera: "FRONT or front_camera".into(),
                        available: scene.cameras.iter().map(|c| c.name.as_str()).collect::<Vec<_>>().join(", "),
                    })?;
                three
                    .iter()
                    .filter(|c| scene.camera(c).is_some())
                    .map(|c| Tile::View { camera: c.to_string(), corner_case: true })
                    .collect()
            }
            Layout::Compare { camera } => {
                let c = need(camera)?;
                vec![
                    Tile::View { camera: c.clone(), corner_case: false },
                    Tile::View { camera: c, corner_case: true },
                    Tile::Bev,
                ]
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_names_layouts() {
        let l: Layout = "compare:FRONT".parse().unwrap();
        assert_eq!(l, Layout::Compare { camera: "FRONT".into() });
        assert_eq!(l.slug(), "compare-FRONT");
        assert_eq!("front3".parse::<Layout>().unwrap(), Layout::FrontTriple);
        assert!("single:".parse::<Layout>().is_err());
        assert!("side".parse::<Layout>().is_err());
    }
}
