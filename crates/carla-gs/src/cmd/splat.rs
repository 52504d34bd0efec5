//! `carla-gs render-ply <model.ply> --camera <camera.json> --out <png> [--device cpu|cpu-f64|cuda]`
//! and `carla-gs bench-splat [--cases NxWxH,... --iters K --devices cpu,cuda] --out <json>` (`cpu`
//! times the f32 CPU path and the f64 reference side by side).
//! The camera JSON is `splat::Camera` (see its docs: width, height, fx, fy, cx, cy,
//! camera_from_world as a row-major 4x4 in OpenCV axes, optional near and far); its image may
//! have at most `render::budget::MAX_PIXELS` pixels.
//! Each `--out` is a file of its own kind (a PNG; a bench-splat JSON) or new: anything else
//! takes `--force` (`out_file`), and it is written whole or not at all.
use anyhow::Context;
use splat::backward::{backward_into, Gradients, Upstream};
use splat::render::{render as rasterize, render_into, Context as RenderContext, Features, Image, RenderOptions};
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub struct RenderArgs {
    model: PathBuf,
    #[arg(long)]
    camera: PathBuf,
    #[arg(long)]
    out: PathBuf,
    /// Background colour r,g,b in [0, 1].
    #[arg(long, default_value = "0,0,0")]
    background: String,
    #[arg(long)]
    antialiased: bool,
    #[arg(long, value_enum, default_value = "cpu")]
    device: super::recon::Device,
    /// Replace an existing --out that is not a PNG.
    #[arg(long)]
    force: bool,
}

fn read_camera(path: &PathBuf) -> anyhow::Result<splat::Camera> {
    let text = std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let cam: splat::Camera =
        serde_json::from_str(&text).with_context(|| format!("{}: not a camera JSON", path.display()))?;
    cam.validate().map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    let what = format!("{}: width x height", path.display());
    render::budget::check_size(&what, cam.width as u64, cam.height as u64)?;
    Ok(cam)
}

pub fn render(a: RenderArgs) -> anyhow::Result<()> {
    use super::out_file::{check_out_file, is_png};
    check_out_file(&a.out, &[&a.model, &a.camera], a.force, "a PNG image", is_png)?;
    let cam = read_camera(&a.camera)?;
    let g = splat::ply::read_ply(&a.model)?;
    g.validate()?;
    let bg: Vec<f64> = a
        .background
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .context("--background: expected r,g,b")?;
    anyhow::ensure!(
        bg.len() == 3 && bg.iter().all(|c| (0.0..=1.0).contains(c)),
        "--background: expected three numbers r,g,b in [0, 1], got {}",
        a.background
    );
    let opts = RenderOptions { background: [bg[0], bg[1], bg[2]], antialiased: a.antialiased, ..Default::default() };
    let t = Instant::now();
    let img = match a.device {
        super::recon::Device::Cpu => splat::fast::render_with_context(&g, &cam, &Features::default(), &opts).0,
        super::recon::Device::CpuF64 => rasterize(&g, &cam, &Features::default(), &opts),
        super::recon::Device::Cuda => {
            let gpu = splat_cuda::Gpu::new().map_err(|e| anyhow::anyhow!("--device cuda: {e}"))?;
            let mut img = Image::default();
            gpu.render(&g, &cam, &Features::default(), &opts, &mut splat_cuda::Session::default(), &mut img)?;
            img
        }
    };
    let ms = t.elapsed().as_secs_f64() * 1e3;
    let bytes: Vec<u8> = img.rgb.iter().flat_map(|c| c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)).collect();
    let buf = image::RgbImage::from_raw(img.width as u32, img.height as u32, bytes).context("image buffer size")?;
    let mut png = std::io::Cursor::new(Vec::new());
    buf.write_to(&mut png, image::ImageFormat::Png).context("encode the PNG")?;
    scene::write_file_atomic(&a.out, png.get_ref())?;
    println!("rendered {} Gaussians at {}x{} in {ms:.1} ms -> {}", g.len(), img.width, img.height, a.out.display());
    Ok(())
}

#[derive(clap::Args)]
pub struct BenchArgs {
    /// Comma-separated cases NxWxH.
    #[arg(long, default_value = "100000x480x320,1000000x1920x1280")]
    cases: String,
    #[arg(long, default_value_t = 3)]
    iters: usize,
    /// Comma-separated devices: cpu (the f32 path and the f64 reference, side by side), cuda.
    #[arg(long, default_value = "cpu")]
    devices: String,
    /// Timed iterations on the GPU (after 3 warm-up ones).
    #[arg(long, default_value_t = 50)]
    gpu_iters: usize,
    /// Also write each case's Gaussians (`gaussians-NxWxH.f32`, see `splat::random::write_f32_rows`)
    /// and, with cuda, its forward RGB (`rgb-NxWxH.f32`, H x W x 3) here, for `tools/bench/`.
    #[arg(long)]
    dump_dir: Option<PathBuf>,
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing --out that is not a bench-splat JSON.
    #[arg(long)]
    force: bool,
}

/// What bench-splat writes: a JSON object whose `benchmark` names the splat rasterizer.
const BENCHMARK: &str = "splat rasterizer, forward and forward+backward per iteration";

fn is_bench_splat(b: &[u8]) -> bool {
    serde_json::from_slice::<serde_json::Value>(b).is_ok_and(|v| v["benchmark"] == BENCHMARK)
}

/// Timed iterations per case at most (a budget on time: the median settles long before).
const MAX_BENCH_ITERS: usize = 100_000;
/// Cases in one `--cases` list at most.
const MAX_BENCH_CASES: usize = 64;

/// `--cases NxWxH,...`, each checked before anything is allocated: N up to
/// [`splat::ply::MAX_GAUSSIANS`], W and H from 1 to [`scene::camera::MAX_CAMERA_SIDE`], W x H up to
/// [`scene::camera::MAX_CAMERA_PIXELS`].
/// A `--cases` entry: its text, and N, W, H.
type BenchCase = (String, (usize, u32, u32));

fn bench_cases(list: &str) -> anyhow::Result<Vec<BenchCase>> {
    let cases: Vec<&str> = list.split(',').map(str::trim).collect();
    anyhow::ensure!(cases.len() <= MAX_BENCH_CASES, "--cases: {} cases; at most {MAX_BENCH_CASES}", cases.len());
    let (max_n, max_side, max_px) =
        (splat::ply::MAX_GAUSSIANS, scene::camera::MAX_CAMERA_SIDE, scene::camera::MAX_CAMERA_PIXELS);
    cases
        .into_iter()
        .map(|case| {
            let v: Vec<u64> = case
                .split('x')
                .map(|s| s.trim().parse())
                .collect::<Result<_, _>>()
                .with_context(|| format!("--cases: `{case}` is not NxWxH"))?;
            anyhow::ensure!(v.len() == 3, "--cases: `{case}` is not NxWxH");
            let (n, w, h) = (v[0], v[1], v[2]);
            anyhow::ensure!(n <= max_n as u64, "--cases: `{case}`: {n} Gaussians; at most {max_n}");
            anyhow::ensure!(
                (1..=max_side).contains(&w) && (1..=max_side).contains(&h) && w * h <= max_px,
                "--cases: `{case}`: a {w}x{h} image; expected sides of 1 to {max_side} and at most {max_px} pixels"
            );
            Ok((case.to_string(), (n as usize, w as u32, h as u32)))
        })
        .collect()
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The CUDA rasterizer on one case: the model and upstream gradients stay on the device (as in a
/// device-side training loop); each iteration is forward + backward, synchronised, host clock.
/// Also one round through the f64 boundary (`Gpu::render` + `backward_into`), as the trainer's
/// `Backend` uses it today.
fn bench_cuda(
    gpu: &splat_cuda::Gpu,
    g: &splat::Gaussians,
    cam: &splat::Camera,
    up: &Upstream,
    iters: usize,
    rgb_dump: Option<PathBuf>,
) -> anyhow::Result<serde_json::Value> {
    let opts = RenderOptions::default();
    let mut sess = splat_cuda::Session::default();
    gpu.upload(&mut sess, g, &Features::default())?;
    gpu.forward_resident(&mut sess, cam, &opts)?;
    gpu.upload_upstream(&mut sess, up)?;
    let (mut fwd, mut both) = (Vec::new(), Vec::new());
    for i in 0..iters + 3 {
        gpu.synchronize()?;
        let t = Instant::now();
        gpu.forward_resident(&mut sess, cam, &opts)?;
        gpu.synchronize()?;
        let f = t.elapsed().as_secs_f64();
        gpu.backward_resident(&mut sess)?;
        gpu.synchronize()?;
        if i >= 3 {
            fwd.push(f);
            both.push(t.elapsed().as_secs_f64());
        }
    }
    let (mut img, mut grads) = (Image::default(), Gradients::default());
    let t = Instant::now();
    gpu.render(g, cam, &Features::default(), &opts, &mut sess, &mut img)?;
    gpu.backward_into(g, &mut sess, up, &mut grads)?;
    let boundary = t.elapsed().as_secs_f64();
    if let Some(path) = rgb_dump {
        let bytes: Vec<u8> = img.rgb.iter().flatten().flat_map(|v| (*v as f32).to_le_bytes()).collect();
        let tmp = path.with_extension("tmp");
        std::fs::write(&tmp, bytes)
            .and_then(|_| std::fs::rename(&tmp, &path))
            .with_context(|| format!("{}: cannot write", path.display()))?;
    }
    Ok(
        serde_json::json!({"device": gpu.describe(), "forward_s": median(&mut fwd), "forward_backward_s": median(&mut both),
        "iters": iters, "intersections": sess.intersections(), "with_f64_host_boundary_s": boundary}),
    )
}

pub fn bench(a: BenchArgs) -> anyhow::Result<()> {
    super::out_file::check_out_file(&a.out, &[], a.force, "a bench-splat JSON", is_bench_splat)?;
    let mut results = Vec::new();
    let devices: Vec<&str> = a.devices.split(',').map(str::trim).collect();
    if let Some(d) = devices.iter().find(|d| !matches!(**d, "cpu" | "cuda")) {
        anyhow::bail!("--devices: `{d}` is neither cpu nor cuda");
    }
    let cpu = devices.contains(&"cpu");
    let gpu = if devices.contains(&"cuda") {
        Some(splat_cuda::Gpu::new().map_err(|e| anyhow::anyhow!("--devices cuda: {e}"))?)
    } else {
        None
    };
    anyhow::ensure!(
        (1..=MAX_BENCH_ITERS).contains(&a.gpu_iters),
        "--gpu-iters {}: expected 1 to {MAX_BENCH_ITERS}",
        a.gpu_iters
    );
    anyhow::ensure!(
        !cpu || (1..=MAX_BENCH_ITERS).contains(&a.iters),
        "--iters {}: expected 1 to {MAX_BENCH_ITERS} (the median of the timed iterations is reported)",
        a.iters
    );
    let cases = bench_cases(&a.cases)?;
    for (case, (n, w, h)) in cases {
        let cam = splat::Camera::at_origin(w, h, 0.8 * w as f64);
        let n_px = w as usize * h as usize;
        let (ones, zeros, zeros3) = (vec![[1.0; 3]; n_px], vec![0.0; n_px], vec![[0.0; 3]; n_px]);
        let up = Upstream { rgb: &ones, alpha: &zeros, depth: &zeros, normal: &zeros3, features: &[] };
        let g = splat::random::random_gaussians(n, &cam, 3, 7);
        if let Some(dir) = &a.dump_dir {
            std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
            let path = dir.join(format!("gaussians-{case}.f32"));
            splat::random::write_f32_rows(&path, &g).with_context(|| format!("{}: cannot write", path.display()))?;
        }
        let opts = RenderOptions::default();
        let (mut fwd, mut both) = (Vec::new(), Vec::new());
        // Like a training loop: the image, context and gradients keep their memory between
        // iterations; upstream gradients d loss / d rgb = 1.
        let mut row = serde_json::json!({"gaussians": n, "width": w, "height": h});
        if let Some(gpu) = &gpu {
            let rgb_dump = a.dump_dir.as_ref().map(|d| d.join(format!("rgb-{case}.f32")));
            let r = bench_cuda(gpu, &g, &cam, &up, a.gpu_iters, rgb_dump)?;
            println!(
                "{n} Gaussians at {w}x{h} on {}: forward {:.3} ms, forward+backward {:.3} ms",
                gpu.describe(),
                r["forward_s"].as_f64().unwrap_or(0.0) * 1e3,
                r["forward_backward_s"].as_f64().unwrap_or(0.0) * 1e3
            );
            row["cuda"] = r;
        }
        if !cpu {
            results.push(row);
            continue;
        }
        let (mut img, mut ctx, mut grads) = (Image::default(), RenderContext::default(), Gradients::default());
        for _ in 0..a.iters {
            let t = Instant::now();
            render_into(&g, &cam, &Features::default(), &opts, &mut img, &mut ctx);
            fwd.push(t.elapsed().as_secs_f64());
            let t2 = Instant::now();
            backward_into(&g, &cam, &Features::default(), &opts, &ctx, &up, &mut grads);
            both.push(fwd[fwd.len() - 1] + t2.elapsed().as_secs_f64());
        }
        let (f, b) = (median(&mut fwd), median(&mut both));
        println!(
            "{n} Gaussians at {w}x{h}, f64 reference: forward {:.3} s ({:.2}/s), forward+backward {:.3} s ({:.2}/s)",
            f,
            1.0 / f,
            b,
            1.0 / b
        );
        let threads = rayon::current_num_threads();
        row["cpu"] = serde_json::json!({"iters": a.iters, "forward_s": f, "forward_backward_s": b, "threads": threads});
        // The f32 path on the same case (one untimed warm-up: its buffers settle).
        let mut fctx = splat::fast::FastContext::default();
        splat::fast::render_into(&g, &cam, &Features::default(), &opts, &mut img, &mut fctx);
        let (mut fwd32, mut both32) = (Vec::new(), Vec::new());
        for _ in 0..a.iters {
            let t = Instant::now();
            splat::fast::render_into(&g, &cam, &Features::default(), &opts, &mut img, &mut fctx);
            fwd32.push(t.elapsed().as_secs_f64());
            let t2 = Instant::now();
            splat::fast::backward_into(&g, &cam, &Features::default(), &opts, &fctx, &up, &mut grads);
            both32.push(fwd32[fwd32.len() - 1] + t2.elapsed().as_secs_f64());
        }
        let (f32_, b32) = (median(&mut fwd32), median(&mut both32));
        println!(
            "{n} Gaussians at {w}x{h}, f32: forward {:.4} s ({:.1}x), forward+backward {:.4} s ({:.1}x)",
            f32_,
            f / f32_,
            b32,
            b / b32
        );
        row["cpu_f32"] = serde_json::json!({"iters": a.iters, "forward_s": f32_, "forward_backward_s": b32,
            "threads": threads, "speedup_forward": f / f32_, "speedup_forward_backward": b / b32});
        results.push(row);
    }
    let json = serde_json::json!({"benchmark": BENCHMARK, "results": results});
    scene::write_file_atomic(&a.out, &serde_json::to_vec_pretty(&json)?)?;
    println!("wrote {}", a.out.display());
    Ok(())
}
