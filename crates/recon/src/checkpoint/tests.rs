//! Checkpoint round trip, damage, and hostile headers whose checksum is valid (issue 28 rows 2
//! and 14): each refused naming the field, before anything is allocated.

use super::*;

fn state() -> TrainState {
    let cam = splat::Camera::at_origin(8, 8, 8.0);
    let model = SceneModel {
        antialiased: false,
        background: splat::random::random_gaussians(7, &cam, 2, 1),
        actors: vec![Actor {
            track_id: "car-1".into(),
            size_lwh: [4.0, 2.0, 1.5],
            gaussians: splat::random::random_gaussians(3, &cam, 2, 2),
        }],
        sky: Sky::new(2, [0.3, 0.4, 0.5]),
    };
    let mut adam = AdamState::new(&model);
    adam.step = 17;
    adam.m[1].means[2] = [1.0, 2.0, 3.0];
    let stats = model
        .sets()
        .map(|g| Stats { grad_sum: vec![0.5; g.len()], seen: vec![3; g.len()], max_radius: vec![2.0; g.len()] })
        .collect();
    TrainState { next_iteration: 17, model, adam, stats, smoothing: vec![] }
}

fn run() -> RunIdentity {
    RunIdentity { scene_name: "s".into(), scene_fingerprint: "0a0b0c0d".into(), config_fingerprint: "01020304".into() }
}

#[test]
fn round_trip_and_damage_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("ckpt.bin");
    let st = state();
    save(&p, &st, &run()).unwrap();
    assert_eq!(load_run(&p).unwrap(), (st, Some(run())));
    let mut bytes = std::fs::read(&p).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x40;
    std::fs::write(&p, &bytes).unwrap();
    let err = load(&p).unwrap_err().to_string();
    assert!(err.contains("ckpt.bin") && err.contains("checksum"), "{err}");
    std::fs::write(&p, &bytes[..100]).unwrap();
    assert!(load(&p).unwrap_err().to_string().contains("ckpt.bin"));
    std::fs::write(&p, b"hello").unwrap();
    assert!(load(&p).unwrap_err().to_string().contains("magic"));
}

/// The header as JSON and the payload of a saved checkpoint.
fn parts(p: &Path) -> (serde_json::Value, Vec<u8>) {
    let bytes = std::fs::read(p).unwrap();
    let hlen = u64::from_le_bytes(bytes[8..16].try_into().unwrap()) as usize;
    let header = serde_json::from_slice(&bytes[16..16 + hlen]).unwrap();
    (header, bytes[16 + hlen..bytes.len() - 4].to_vec())
}

/// Writes a checkpoint from a header and payload with a correct checksum.
fn forge(p: &Path, header: &serde_json::Value, payload: &[u8]) {
    let h = serde_json::to_vec(header).unwrap();
    let mut out = MAGIC.to_vec();
    out.extend_from_slice(&(h.len() as u64).to_le_bytes());
    out.extend_from_slice(&h);
    out.extend_from_slice(payload);
    let crc = crc32c::crc32c(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    std::fs::write(p, out).unwrap();
}

#[test]
fn hostile_headers_with_valid_checksums_are_refused_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("ckpt.bin");
    save(&p, &state(), &run()).unwrap();
    let (good, payload) = parts(&p);
    let sky_bytes = 3 * 6 * 2 * 2 * 3 * 8;
    let refused = |edit: &dyn Fn(&mut serde_json::Value), payload: &[u8], needle: &str| {
        let mut h = good.clone();
        edit(&mut h);
        forge(&p, &h, payload);
        let e = load(&p).unwrap_err().to_string();
        assert!(e.contains("ckpt.bin: corrupt checkpoint") && e.contains(needle), "expected `{needle}` in: {e}");
    };
    // Row 2: sky_res 2^32 with the sky payload removed (panicked: index out of bounds).
    let no_sky = &payload[..payload.len() - sky_bytes];
    refused(&|h| h["sky_res"] = (1u64 << 32).into(), no_sky, "`sky_res` must be in 1..=512, got 4294967296");
    refused(&|h| h["sets"][0]["len"] = (1u64 << 62).into(), &payload, "`sets[0].len` must be in");
    refused(&|h| h["sets"][0]["sh_degree"] = 9.into(), &payload, "`sets[0].sh_degree`");
    refused(&|h| h["sets"][0]["len"] = 8.into(), &payload, "the header's sizes need");
    // Row 14: next_iteration 1e9, an actor without a track, a duplicated track.
    refused(&|h| h["next_iteration"] = 1_000_000_000u64.into(), &payload, "`next_iteration` must be in 0..=1000000");
    refused(&|h| h["sets"][1]["track_id"] = serde_json::Value::Null, &payload, "must name its track");
    refused(&|h| h["sets"][1]["size_lwh"][0] = (-1.0).into(), &payload, "`sets[1].size_lwh`");
    // NaN in a parameter and in the sky.
    let mut nan = payload.clone();
    nan[8..16].copy_from_slice(&f64::NAN.to_le_bytes());
    refused(&|_| {}, &nan, "`sets[0].means`[1] is NaN");
    let mut inf = payload.clone();
    let at = payload.len() - sky_bytes;
    inf[at..at + 8].copy_from_slice(&f64::INFINITY.to_le_bytes());
    refused(&|_| {}, &inf, "`sky.texels`[0] is inf");
    // The untouched header and payload still load.
    forge(&p, &good, &payload);
    assert_eq!(load(&p).unwrap(), state());
}

/// A checkpoint that is not a regular file (a link to `/dev/zero`) or is larger than a checkpoint
/// of the most Gaussians can be is refused before it is read.
#[test]
fn a_checkpoint_that_is_not_a_regular_file_is_refused_unread() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("checkpoint.bin");
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink("/dev/zero", &p).unwrap();
        let e = load_run(&p).unwrap_err().to_string();
        assert!(e.contains("checkpoint.bin") && e.contains("not a regular file"), "{e}");
        std::fs::remove_file(&p).unwrap();
    }
    let f = std::fs::File::create(&p).unwrap();
    f.set_len(max_bytes() + 1).unwrap(); // sparse
    let e = load_run(&p).unwrap_err().to_string();
    assert!(e.contains(&format!("{} bytes, more than the {}", max_bytes() + 1, max_bytes())), "{e}");
    assert!(max_bytes() > 14_000_000_000, "10M Gaussians of degree 3 fit");
}
