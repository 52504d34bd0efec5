//! Decides whether a record is a Waymo v1 `Frame` or a WOMD `Scenario` from its content.
//!
//! The two messages disagree on wire types for their low field numbers (Frame 1 = message,
//! 2 = varint; Scenario 1 = double, 2 = message), so a record of one kind fails to decode as the
//! other. On top of decoding, each kind must carry its identifying fields (Frame: context, pose,
//! timestamp; Scenario: id and timestamps), so random bytes that happen to decode are refused.

use crate::proto::{Frame, Scenario};
use prost::Message;

#[derive(Debug)]
pub enum Decoded {
    Frame(Box<Frame>),
    Scenario(Box<Scenario>),
}

impl Decoded {
    pub fn kind_name(&self) -> &'static str {
        match self {
            Decoded::Frame(_) => "Waymo Frame",
            Decoded::Scenario(_) => "WOMD Scenario",
        }
    }
}

/// Which kind of content to accept.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Expect {
    Auto,
    Frame,
    Scenario,
    /// A KITTI odometry sequence folder (`kitti`).
    KittiOdometry,
    /// An instant-ngp / nerfstudio `transforms.json` folder (`transforms_json`).
    TransformsJson,
    /// A PandaSet sequence folder (`pandaset`).
    Pandaset,
}

/// Decodes a record; the error says why neither kind fits.
pub fn decode_record(data: &[u8], expect: Expect) -> Result<Decoded, String> {
    let frame = || match Frame::decode(data) {
        Ok(f) if f.context.is_some() && f.pose.is_some() && f.timestamp_micros.is_some() => {
            Ok(Decoded::Frame(Box::new(f)))
        }
        Ok(_) => Err("as a Frame it lacks context, pose or timestamp_micros".to_string()),
        Err(e) => Err(format!("as a Frame: {e}")),
    };
    let scenario = || match Scenario::decode(data) {
        Ok(s) if s.scenario_id.is_some() && !s.timestamps_seconds.is_empty() => Ok(Decoded::Scenario(Box::new(s))),
        Ok(_) => Err("as a Scenario it lacks scenario_id or timestamps_seconds".to_string()),
        Err(e) => Err(format!("as a Scenario: {e}")),
    };
    match expect {
        Expect::Frame => frame(),
        Expect::Scenario => scenario(),
        Expect::Auto => frame().or_else(|a| scenario().map_err(|b| format!("{a}; {b}"))),
        Expect::KittiOdometry | Expect::TransformsJson | Expect::Pandaset => {
            Err("folder formats are not TFRecord records".to_string())
        }
    }
}
