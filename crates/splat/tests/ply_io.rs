//! PLY round trip in the standard 3DGS layout, reading a degree-0 file written by hand, and
//! errors that name the problem.

use splat::ply::{read_ply, write_ply};
use splat::Gaussians;

fn model(n: usize, degree: usize) -> Gaussians {
    let k = (degree + 1) * (degree + 1);
    // Values a PLY file (f32) holds exactly.
    let f = |i: usize, j: usize, d: f32| ((((i * 31 + j * 7) % 97) as f32 / 13.0 - 3.0) / d) as f64;
    Gaussians {
        means: (0..n).map(|i| [f(i, 0, 1.0), f(i, 1, 1.0), f(i, 2, 1.0)]).collect(),
        log_scales: (0..n).map(|i| [f(i, 3, 3.0), f(i, 4, 3.0), f(i, 5, 3.0)]).collect(),
        rotations: (0..n).map(|i| [1.0, f(i, 6, 10.0), f(i, 7, 10.0), f(i, 8, 10.0)]).collect(),
        opacity_logits: (0..n).map(|i| f(i, 9, 1.0)).collect(),
        sh_degree: degree,
        sh: (0..n * k * 3).map(|j| f(j, 10, 5.0)).collect(),
    }
}

#[test]
fn round_trip_every_degree() {
    let dir = tempfile::tempdir().unwrap();
    for degree in 0..=3 {
        let g = model(50, degree);
        g.validate().unwrap();
        let p = dir.path().join(format!("m{degree}.ply"));
        write_ply(&p, &g).unwrap();
        let back = read_ply(&p).unwrap();
        assert_eq!(back, g, "degree {degree}");
        // Binary little-endian floats: header + 4 bytes per property per Gaussian.
        let props = 17 + 3 * ((degree + 1) * (degree + 1) - 1);
        let len = std::fs::metadata(&p).unwrap().len() as usize;
        assert!(len >= 50 * props * 4 && len < 50 * props * 4 + 2048, "size {len}");
    }
}

#[test]
fn reads_a_degree_zero_file_written_by_hand() {
    // The minimal layout many tools export: no normals, no f_rest, ASCII.
    let text = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n\
property float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\nproperty float opacity\n\
property float scale_0\nproperty float scale_1\nproperty float scale_2\n\
property float rot_0\nproperty float rot_1\nproperty float rot_2\nproperty float rot_3\nend_header\n\
1 2 3 0.1 0.2 0.3 0.5 -1 -2 -3 1 0 0 0\n-1 0 4 0 0 0 -0.5 0 0 0 0.7 0.7 0 0\n";
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("dc.ply");
    std::fs::write(&p, text).unwrap();
    let g = read_ply(&p).unwrap();
    assert_eq!(g.sh_degree, 0);
    assert_eq!(g.len(), 2);
    assert_eq!(g.means[0], [1.0, 2.0, 3.0]);
    let f32s = |v: [f32; 3]| v.map(|x| x as f64);
    assert_eq!(g.sh_of(0), &f32s([0.1, 0.2, 0.3]));
    assert_eq!(g.log_scales[0], [-1.0, -2.0, -3.0]);
    assert_eq!(g.rotations[1], [0.7f32 as f64, 0.7f32 as f64, 0.0, 0.0]);
    assert_eq!(g.opacity_logits[1], -0.5);
}

#[test]
fn errors_name_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.ply");
    std::fs::write(&p, "not a ply").unwrap();
    assert!(read_ply(&p).unwrap_err().to_string().contains("not a readable PLY"));
    std::fs::write(&p, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n").unwrap();
    let e = read_ply(&p).unwrap_err().to_string();
    assert!(e.contains("no `f_dc_0` property"), "{e}");
    let missing = dir.path().join("none.ply");
    assert!(read_ply(&missing).unwrap_err().to_string().contains("none.ply"));
}

#[test]
fn bad_vertices_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("v.ply");
    let head = |opacity: &str, x: &str| {
        format!(
            "ply\nformat ascii 1.0\nelement vertex 2\n{x}\nproperty float y\nproperty float z\nproperty uchar red\n\
property float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\nproperty {opacity} opacity\n\
property float scale_0\nproperty float scale_1\nproperty float scale_2\n\
property float rot_0\nproperty float rot_1\nproperty float rot_2\nproperty float rot_3\nend_header\n"
        )
    };
    let x = "property float x";
    // Extra properties of other types (a colour) are ignored.
    let good = "1 2 3 7 0.1 0.2 0.3 0 -1 -2 -3 1 0 0 0\n1 2 3 9 0.1 0.2 0.3 0 -1 -2 -3 1 0 0 0\n";
    std::fs::write(&p, head("float", x) + good).unwrap();
    assert_eq!(read_ply(&p).unwrap().len(), 2);
    // A value that is not finite (1e39 is infinite in f32): the vertex and the property.
    std::fs::write(
        &p,
        head("float", x) + "1 2 3 7 0.1 0.2 0.3 0 -1 -2 -3 1 0 0 0\n1 2 3 9 0.1 0.2 0.3 0 -1 1e39 -3 1 0 0 0\n",
    )
    .unwrap();
    let e = read_ply(&p).unwrap_err().to_string();
    assert!(e.contains("vertex 1") && e.contains("`scale_1`") && e.contains("not finite"), "{e}");
    // One of ours as an integer: refused, naming it.
    std::fs::write(&p, head("int", x) + good).unwrap();
    let e = read_ply(&p).unwrap_err().to_string();
    assert!(e.contains("v.ply") && e.contains("opacity"), "{e}");
}

/// The 3DGS degree-0 header, binary little-endian, with `count` vertices.
fn binary_header(count: &str) -> String {
    let props: String = [
        "x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1",
        "rot_2", "rot_3",
    ]
    .iter()
    .map(|p| format!("property float {p}\n"))
    .collect();
    format!("ply\nformat binary_little_endian 1.0\nelement vertex {count}\n{props}end_header\n")
}

#[test]
fn a_file_linked_to_an_endless_device_or_not_a_file_is_refused() {
    // Fuzz finding: background.ply -> /dev/zero aborted the process (a 4 GiB header line).
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("background.ply");
    std::os::unix::fs::symlink("/dev/zero", &p).unwrap();
    let start = std::time::Instant::now();
    let e = read_ply(&p).unwrap_err().to_string();
    assert!(e.contains("background.ply: is a character device; expected a regular file"), "{e}");
    assert!(start.elapsed() < std::time::Duration::from_secs(5));
    let e = read_ply(dir.path()).unwrap_err().to_string();
    assert!(e.contains("is a directory; expected a regular file"), "{e}");
    // Larger than the budget (a sparse file, no disk used): refused before reading.
    let big = dir.path().join("big.ply");
    std::fs::File::create(&big).unwrap().set_len(splat::ply::MAX_PLY_BYTES + 1).unwrap();
    let e = read_ply(&big).unwrap_err().to_string();
    assert!(e.contains("4961048577 bytes, more than the 4961048576 a PLY file may have"), "{e}");
}

#[test]
fn a_header_line_without_end_is_cut_at_the_header_budget() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("long.ply");
    let mut text = b"ply\nformat binary_little_endian 1.0\ncomment ".to_vec();
    text.resize(text.len() + 2 * splat::ply::MAX_HEADER_BYTES as usize, b'x');
    std::fs::write(&p, &text).unwrap();
    let e = read_ply(&p).unwrap_err().to_string();
    assert!(e.contains("long.ply: not a readable PLY file: no `end_header` within its first 1048576 bytes"), "{e}");
}

#[test]
fn declared_counts_must_fit_the_budget_and_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("c.ply");
    let vertex = [0f32, 0., 0., 0., 0., 0., 0., 0., 0., 0., 1., 0., 0., 0.];
    let bytes: Vec<u8> = vertex.iter().flat_map(|v| v.to_le_bytes()).collect();
    // One vertex declared and present: read.
    std::fs::write(&p, [binary_header("1").as_bytes(), &bytes].concat()).unwrap();
    assert_eq!(read_ply(&p).unwrap().len(), 1);
    // Ten million declared, one present: refused before reading, naming the sizes.
    std::fs::write(&p, [binary_header("10000000").as_bytes(), &bytes].concat()).unwrap();
    let e = read_ply(&p).unwrap_err().to_string();
    assert!(
        e.contains("`element vertex 10000000` needs at least 560000000 bytes (56 an element), more than the 56 after the header"),
        "{e}"
    );
    // More than the Gaussian budget.
    std::fs::write(&p, [binary_header("10000001").as_bytes(), &bytes].concat()).unwrap();
    let e = read_ply(&p).unwrap_err().to_string();
    assert!(e.contains("`element vertex 10000001`: more than the 10000000 elements"), "{e}");
    // ASCII: at least two bytes a value.
    let ascii = binary_header("3").replace("binary_little_endian", "ascii");
    std::fs::write(&p, ascii + "0 0 0 0 0 0 0 0 0 0 1 0 0 0\n").unwrap();
    let e = read_ply(&p).unwrap_err().to_string();
    assert!(e.contains("`element vertex 3` needs at least 84 bytes (28 an element), more than the 28"), "{e}");
    // An element of no properties takes no bytes: refused, however many.
    let empty = binary_header("1").replace("end_header", "element nothing 1000000\nend_header");
    std::fs::write(&p, [empty.as_bytes(), &bytes].concat()).unwrap();
    let e = read_ply(&p).unwrap_err().to_string();
    assert!(e.contains("`element nothing 1000000` has no properties"), "{e}");
}
