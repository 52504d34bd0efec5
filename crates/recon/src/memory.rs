//! The memory the training views' targets take, checked before any image is decoded. A full-size
//! log (PandaSet: 6 cameras x 80 frames at 1920x1080, a billion pixels) at scale 1 asks for tens of
//! GB; loading it view by view until the allocator fails ends in the kernel's OOM killer, with no
//! message and nothing written. So the need is computed from the scene (every image's size at the
//! training scale, times the bytes a pixel's targets take, priors included where the scene has
//! them) and compared with what this process may use: `MemAvailable` from `/proc/meminfo`,
//! lowered to what its cgroups leave where they set a limit (a Slurm job, a container), or
//! `CARLA_GS_HOST_MEMORY` (bytes, or with a K/M/G suffix) where the user sets it. A refusal names
//! the views, their size, the need, what is available, and the largest scale of 1/2, 1/4, 1/8 that
//! fits.

use crate::camera::scaled_size;
use crate::error::ReconError;
use scene::Scene;

/// The share of the available memory the targets may take: the model, its Adam moments, the
/// rasterizer's buffers and the outputs need the rest.
pub const TARGET_SHARE: f64 = 0.7;

/// The environment variable that sets the host memory budget (overrides what the system reports).
pub const BUDGET_ENV: &str = "CARLA_GS_HOST_MEMORY";

/// Bytes one pixel's targets take in memory: the image, and with priors the depth, normal,
/// supervision mask and `L_geo` weight (`loss::Targets`).
pub fn bytes_per_pixel(with_priors: bool) -> u64 {
    use std::mem::size_of;
    let rgb = size_of::<[f32; 3]>();
    // depth, L_geo weight, normal, mask
    let priors = size_of::<f32>() * 2 + size_of::<[f32; 3]>() + size_of::<bool>();
    (rgb + if with_priors { priors } else { 0 }) as u64
}

/// A view with pixels left out of training (`protocol`) holds two more f32 a pixel
/// (`Targets::keep`, `Targets::ssim_keep`).
pub const LEFT_OUT_BYTES_PER_PIXEL: u64 = 8;

/// Pixels of every image of `scene` at `scale` in the frames `keep` keeps, and the number of images.
pub fn pixels_at(scene: &Scene, scale: f64, keep: &dyn Fn(usize) -> bool) -> (u64, usize) {
    let mut pixels = 0u64;
    let mut images = 0usize;
    for f in scene.frames.iter().filter(|f| keep(f.index)) {
        for im in &f.images {
            if let Some(cam) = scene.camera(&im.camera) {
                let (w, h) = scaled_size(cam.width, cam.height, scale);
                pixels += w as u64 * h as u64;
                images += 1;
            }
        }
    }
    (pixels, images)
}

/// The bytes this process may use: `CARLA_GS_HOST_MEMORY` if set, else `MemAvailable` lowered to
/// what its cgroups leave ([`cgroup_remaining`]) and to what its address-space limit leaves
/// ([`address_space_left`]); `None` where neither is known (then nothing is
/// refused).
pub fn available_bytes() -> Result<Option<u64>, ReconError> {
    if let Some(v) = std::env::var_os(BUDGET_ENV) {
        let s = v.to_string_lossy();
        return parse_bytes(&s).map(Some).ok_or_else(|| {
            ReconError::Config(format!("{BUDGET_ENV}={s}: expected bytes, or a number with K, M or G"))
        });
    }
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok();
    let available = meminfo.as_deref().and_then(|m| meminfo_field(m, "MemAvailable:"));
    let cgroup = std::fs::read_to_string("/proc/self/cgroup")
        .ok()
        .and_then(|c| cgroup_remaining(std::path::Path::new("/sys/fs/cgroup"), &c));
    let limits = std::fs::read_to_string("/proc/self/limits").ok();
    let status = std::fs::read_to_string("/proc/self/status").ok();
    let space = limits.as_deref().zip(status.as_deref()).and_then(|(l, s)| address_space_left(l, s));
    Ok([available, cgroup, space].into_iter().flatten().min())
}

/// What the soft address-space limit (`ulimit -v`, "Max address space" of `/proc/self/limits`)
/// leaves above the process's current size (`VmSize` of `/proc/self/status`); `None` when unlimited.
pub fn address_space_left(limits: &str, status: &str) -> Option<u64> {
    let line = limits.lines().find(|l| l.starts_with("Max address space"))?;
    let limit: u64 = line["Max address space".len()..].split_whitespace().next()?.parse().ok()?;
    let size = meminfo_field(status, "VmSize:").unwrap_or(0);
    Some(limit.saturating_sub(size))
}

/// Bytes in KiB, MiB or GiB, one decimal.
pub fn human(bytes: u64) -> String {
    let b = bytes as f64;
    match bytes {
        0..0x10_0000 => format!("{:.1} KiB", b / 1024.0),
        0x10_0000..0x4000_0000 => format!("{:.1} MiB", b / (1u64 << 20) as f64),
        _ => format!("{:.1} GiB", b / (1u64 << 30) as f64),
    }
}

/// `<number>[K|M|G]` (binary units) in bytes.
pub fn parse_bytes(s: &str) -> Option<u64> {
    let s = s.trim();
    let (num, mult) = match s.char_indices().last()? {
        (i, 'K' | 'k') => (&s[..i], 1u64 << 10),
        (i, 'M' | 'm') => (&s[..i], 1 << 20),
        (i, 'G' | 'g') => (&s[..i], 1 << 30),
        _ => (s, 1),
    };
    let x: f64 = num.trim().parse().ok()?;
    (x.is_finite() && x >= 0.0 && x * (mult as f64) < u64::MAX as f64).then_some((x * mult as f64) as u64)
}

/// A `Name:   123 kB` field of `/proc/meminfo`, in bytes.
fn meminfo_field(meminfo: &str, name: &str) -> Option<u64> {
    let line = meminfo.lines().find(|l| l.starts_with(name))?;
    let kb: u64 = line[name.len()..].trim().trim_end_matches("kB").trim().parse().ok()?;
    kb.checked_mul(1024)
}

/// What this process's cgroups leave (limit minus use, the least over the group and its
/// ancestors: a Slurm job's limit sits on the job, its steps below it), from `/proc/self/cgroup`
/// (`proc_cgroup`) under the cgroup mount `root`: v2 (`0::<path>`: `memory.max`,
/// `memory.current`) or v1 (the `memory` controller's line: `memory/<path>/memory.limit_in_bytes`,
/// `memory.usage_in_bytes`). `None` where no level sets a limit or none can be read.
pub fn cgroup_remaining(root: &std::path::Path, proc_cgroup: &str) -> Option<u64> {
    let read = |p: std::path::PathBuf| std::fs::read_to_string(p).ok().and_then(|s| s.trim().parse::<u64>().ok());
    let mut least: Option<u64> = None;
    for line in proc_cgroup.lines() {
        let mut parts = line.splitn(3, ':');
        let (Some(_), Some(controllers), Some(path)) = (parts.next(), parts.next(), parts.next()) else { continue };
        let (base, limit_file, use_file) = if controllers.is_empty() {
            (root.to_path_buf(), "memory.max", "memory.current")
        } else if controllers.split(',').any(|c| c == "memory") {
            (root.join("memory"), "memory.limit_in_bytes", "memory.usage_in_bytes")
        } else {
            continue;
        };
        let mut dir = Some(std::path::Path::new(path.trim_start_matches('/')));
        while let Some(d) = dir {
            let at = base.join(d);
            // "max" (v2) does not parse; v1 reports no limit as a number near 2^63.
            if let (Some(limit), Some(used)) = (read(at.join(limit_file)), read(at.join(use_file))) {
                if limit < 1 << 60 {
                    let left = limit.saturating_sub(used);
                    least = Some(least.map_or(left, |l| l.min(left)));
                }
            }
            dir = d.parent();
        }
    }
    least
}

/// `None` when `need` bytes fit [`TARGET_SHARE`] of `available`; else what to do: a trained
/// model's scale is fixed (`!training`); a training scale can drop to the largest of 1/2, 1/4 or 1/8
/// of `scale` whose need (`need_at(that scale)`) fits.
pub fn over_budget(
    need: u64,
    available: u64,
    scale: f64,
    training: bool,
    need_at: &dyn Fn(f64) -> u64,
) -> Option<String> {
    let budget = (available as f64 * TARGET_SHARE) as u64;
    if need <= budget {
        return None;
    }
    if !training {
        return Some(format!("the model was trained at scale {scale}: score it where more memory is free"));
    }
    Some(match [0.5, 0.25, 0.125].into_iter().map(|f| scale * f).find(|s| need_at(*s) <= budget) {
        Some(s) => format!("train at --scale {s} (the `scale` key) or on fewer frames or cameras"),
        None => "train on fewer frames or cameras".into(),
    })
}

/// Refuses when the views of `scene` at `scale` in the frames `keep` keeps need more than
/// [`TARGET_SHARE`] of `available`. `training`: the scale can be chosen (the refusal names one that
/// fits); else it is a trained model's (scoring), and the refusal says so.
/// `extra_per_pixel` bytes a pixel come on top of the targets' own (`LEFT_OUT_BYTES_PER_PIXEL`
/// under a protocol, counted for every view though only the views with left-out pixels hold them).
pub fn check_views(
    scene: &Scene,
    scale: f64,
    with_priors: bool,
    extra_per_pixel: u64,
    keep: &dyn Fn(usize) -> bool,
    training: bool,
    available: Option<u64>,
) -> Result<u64, ReconError> {
    let per_pixel = bytes_per_pixel(with_priors) + extra_per_pixel;
    let need_at = |s: f64| pixels_at(scene, s, keep).0.saturating_mul(per_pixel);
    let need = need_at(scale);
    let Some(available) = available else { return Ok(need) };
    let Some(hint) = over_budget(need, available, scale, training, &need_at) else { return Ok(need) };
    let images = pixels_at(scene, scale, keep).1;
    let size = scene.cameras.iter().map(|c| scaled_size(c.width, c.height, scale)).max().unwrap_or((0, 0));
    Err(ReconError::Memory(format!(
        "the {images} views at scale {scale} (up to {}x{} pixels{}) need {} for their targets; {} is \
         available and the targets may take {:.0} % of it ({BUDGET_ENV} sets the budget): {hint}",
        size.0,
        size.1,
        if with_priors { ", with priors" } else { "" },
        human(need),
        human(available),
        TARGET_SHARE * 100.0,
    )))
}

/// Bytes one Gaussian of degree `sh_degree` takes while training: its parameters, their Adam
/// moments and gradient, its copy in the composed world and its density statistics.
pub fn bytes_per_gaussian(sh_degree: usize) -> u64 {
    let params = (3 + 3 + 4 + 1 + splat::sh::sh_coeffs(sh_degree) * 3) as u64;
    (5 * params + 3) * std::mem::size_of::<f64>() as u64
}

/// The most Gaussians a run of `cfg` on a scene with `actor_tracks` tracked objects can hold: the
/// start (at most `init.max_points` background points and `max(init.actor_points, 50)` per
/// actor) or `densify.max_gaussians`, whichever is larger.
pub fn most_gaussians(cfg: &crate::TrainConfig, actor_tracks: usize) -> u64 {
    let per_actor = cfg.init.actor_points.max(50) as u64;
    let start = (cfg.init.max_points as u64).saturating_add(per_actor.saturating_mul(actor_tracks as u64));
    start.max(cfg.densify.max_gaussians as u64)
}

/// Refuses a config whose Gaussians ([`most_gaussians`]), with the views' targets (`targets`
/// bytes), would not fit `available`, before anything is allocated: the error gives the numbers
/// and the keys to lower. `None`: nothing is known, nothing refused.
pub fn check_model(
    cfg: &crate::TrainConfig,
    actor_tracks: usize,
    targets: u64,
    available: Option<u64>,
) -> Result<(), ReconError> {
    let Some(available) = available else { return Ok(()) };
    let most = most_gaussians(cfg, actor_tracks);
    let each = bytes_per_gaussian(cfg.stored_degree());
    let need = most.saturating_mul(each);
    if need.saturating_add(targets) <= available {
        return Ok(());
    }
    Err(ReconError::Memory(format!(
        "the settings allow up to {most} Gaussians (densify.max_gaussians = {}; the start, init.max_points = \
         {} and {actor_tracks} actors of up to max(init.actor_points = {}, 50)), which take {} while \
         training ({each} bytes each at sh_degree {}), besides {} for the views' targets; {} is \
         available ({BUDGET_ENV} sets the budget): lower densify.max_gaussians, init.max_points or \
         init.actor_points",
        cfg.densify.max_gaussians,
        cfg.init.max_points,
        cfg.init.actor_points,
        human(need),
        cfg.stored_degree(),
        human(targets),
        human(available),
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_binary_suffixes() {
        assert_eq!(parse_bytes("1024"), Some(1024));
        assert_eq!(parse_bytes("2K"), Some(2048));
        assert_eq!(parse_bytes("1.5G"), Some(3 << 29));
        assert_eq!(parse_bytes(" 64 M "), Some(64 << 20));
        for bad in ["", "G", "-1G", "lots", "1e30G", "NaN"] {
            assert_eq!(parse_bytes(bad), None, "{bad}");
        }
    }

    /// The estimate is the size of what `load_views` keeps: a change of a target's type changes it.
    #[test]
    fn bytes_per_pixel_is_what_targets_hold() {
        let n = 10;
        let t = crate::loss::Targets {
            rgb: vec![Default::default(); n],
            depth: Some(vec![Default::default(); n]),
            normal: Some(vec![Default::default(); n]),
            mask: Some(vec![Default::default(); n]),
            geo_weight: Some(vec![Default::default(); n]),
            keep: None,
            ssim_keep: None,
        };
        use std::mem::size_of_val as size;
        let priors = size(t.depth.as_deref().unwrap())
            + size(t.normal.as_deref().unwrap())
            + size(t.mask.as_deref().unwrap())
            + size(t.geo_weight.as_deref().unwrap());
        assert_eq!(bytes_per_pixel(false) * n as u64, size(t.rgb.as_slice()) as u64);
        assert_eq!(bytes_per_pixel(true) * n as u64, (size(t.rgb.as_slice()) + priors) as u64);
        assert_eq!(human(331_776), "324.0 KiB");
        assert_eq!(human(34 << 30), "34.0 GiB");
    }

    /// A limit on a parent group counts (a Slurm job's, with the step below it), "max" and v1's
    /// near-2^63 mean none, and v1's memory controller is found among the others.
    #[test]
    fn cgroup_limits_are_read_up_the_hierarchy() {
        let tmp = tempfile::tempdir().unwrap();
        let put = |rel: &str, v: &str| {
            let p = tmp.path().join(rel);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, v).unwrap();
        };
        put("job/memory.max", "8000\n");
        put("job/memory.current", "3000\n");
        put("job/step/memory.max", "max\n");
        put("job/step/memory.current", "2000\n");
        put("memory.max", "max\n");
        put("memory.current", "1\n");
        assert_eq!(cgroup_remaining(tmp.path(), "0::/job/step\n"), Some(5000));
        assert_eq!(cgroup_remaining(tmp.path(), "0::/\n"), None);
        put("memory/app/memory.limit_in_bytes", "9223372036854771712");
        put("memory/app/memory.usage_in_bytes", "10");
        put("memory/memory.limit_in_bytes", "1000");
        put("memory/memory.usage_in_bytes", "10");
        let v1 = "9:name=systemd:/\n4:cpuacct,memory:/app\n0::/elsewhere\n";
        assert_eq!(cgroup_remaining(tmp.path(), v1), Some(990));
        assert_eq!(cgroup_remaining(tmp.path(), "garbage\n"), None);
    }

    #[test]
    fn meminfo_is_read_in_bytes() {
        let m = "MemTotal:       24000000 kB\nMemFree:  100 kB\nMemAvailable:   22000000 kB\n";
        assert_eq!(meminfo_field(m, "MemAvailable:"), Some(22_000_000 * 1024));
        assert_eq!(meminfo_field(m, "SwapTotal:"), None);
    }

    #[test]
    fn gaussians_past_the_memory_budget_are_refused_with_the_numbers() {
        let cfg = crate::TrainConfig::default();
        // 200k Gaussians of degree 3 at 2,384 bytes: 455 MiB.
        assert_eq!(bytes_per_gaussian(3), 2384);
        assert_eq!(most_gaussians(&cfg, 2), 200_000);
        assert!(check_model(&cfg, 2, 1 << 20, Some(1 << 30)).is_ok());
        assert!(check_model(&cfg, 2, 1 << 20, None).is_ok());
        let mut big = cfg.clone();
        big.densify.max_gaussians = 10_000_000;
        // A run long enough to reach degree 3 stores it...
        big.iterations = 3001;
        let e = check_model(&big, 2, 1 << 20, Some(8 << 30)).unwrap_err().to_string();
        assert!(e.contains("up to 10000000 Gaussians") && e.contains("22.2 GiB") && e.contains("8.0 GiB"), "{e}");
        assert!(e.contains("at sh_degree 3"), "{e}");
        // ...one that ends before degree 2 is drawn stores degree 1: 944 bytes a Gaussian.
        big.iterations = 1500;
        assert_eq!(bytes_per_gaussian(1), 944);
        let e = check_model(&big, 2, 1 << 20, Some(8 << 30)).unwrap_err().to_string();
        assert!(e.contains("8.8 GiB") && e.contains("at sh_degree 1"), "{e}");
        let mut init = cfg;
        init.init.max_points = 10_000_000;
        init.init.actor_points = 10_000_000;
        assert_eq!(most_gaussians(&init, 9), 100_000_000);
        let e = check_model(&init, 9, 0, Some(8 << 30)).unwrap_err().to_string();
        assert!(e.contains("init.max_points = 10000000") && e.contains("9 actors"), "{e}");
    }

    #[test]
    fn the_address_space_limit_lowers_what_is_available() {
        let limits = "Limit                     Soft Limit           Hard Limit           Units     \n\
                      Max address space         4096000000           unlimited            bytes     \n";
        let status = "Name:\tcarla-gs\nVmSize:\t   96000 kB\n";
        assert_eq!(address_space_left(limits, status), Some(4_096_000_000 - 96_000 * 1024));
        let unlimited = "Max address space         unlimited            unlimited            bytes     \n";
        assert_eq!(address_space_left(unlimited, status), None);
    }
}
