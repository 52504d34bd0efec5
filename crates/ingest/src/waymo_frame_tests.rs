//! Unit tests of `waymo_frame`: a camera calibration whose intrinsics do not fit its image.

use super::*;

fn calibration(intrinsic: [f64; 4]) -> proto::CameraCalibration {
    let identity = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    proto::CameraCalibration {
        name: Some(1),
        intrinsic: intrinsic.iter().copied().chain([0.0; 5]).collect(),
        extrinsic: Some(proto::Transform { transform: identity.to_vec() }),
        width: Some(960),
        height: Some(540),
        rolling_shutter_direction: None,
    }
}

#[test]
fn implausible_camera_intrinsics_are_refused_naming_the_entry() {
    let file = Path::new("seg.tfrecord");
    convert_camera(file, 0, 0, &calibration([1000.0, 1000.0, 480.0, 270.0])).unwrap();
    let e = convert_camera(file, 3, 0, &calibration([1e-300, 1000.0, 480.0, 270.0])).unwrap_err().to_string();
    assert!(e.contains("record 3") && e.contains("intrinsic[0]") && e.contains("[9.6, 960000.0]"), "{e}");
    let e = convert_camera(file, 3, 0, &calibration([1000.0, 1000.0, -900000.0, 270.0])).unwrap_err().to_string();
    assert!(e.contains("intrinsic[2]") && e.contains("-900000.0") && e.contains("[-960.0, 1920.0]"), "{e}");
}
