//! The device radix sort (`Gpu::sort_pairs`, the sort every forward pass runs twice) against
//! the standard library's stable sort on the same bits: sizes around the 4,096-pair chunk and
//! the 1,024-value scan block, and large enough for three scan levels; keys uniform, all equal,
//! descending, of three values, varying in the top byte only, and with random bits above the
//! sorted range (which must be ignored, the order of equal sorted bits kept). Values are the
//! input positions, so a stable result is exactly one permutation. Without a CUDA driver or GPU
//! the test prints SKIP and the reason.

use splat::random::XorShift;

#[path = "common/gpu.rs"]
mod common_gpu;
use common_gpu::gpu;

fn mask(bits: &std::ops::Range<u32>) -> u32 {
    let width = bits.end - bits.start;
    let low = if width >= 32 { u32::MAX } else { (1u32 << width) - 1 };
    low << bits.start
}

fn keys_of(kind: &str, n: usize, r: &mut XorShift) -> Vec<u32> {
    let mut next = || (r.uniform() * 4_294_967_296.0) as u32;
    match kind {
        "uniform" => (0..n).map(|_| next()).collect(),
        "equal" => vec![0x1234_5678; n],
        "descending" => (0..n).map(|i| (n - i) as u32).collect(),
        "three" => (0..n).map(|_| [7u32, 0x00ff_0000, 0xffff_ffff][(next() % 3) as usize]).collect(),
        "top byte" => (0..n).map(|_| next() & 0xff00_0000).collect(),
        _ => unreachable!("{kind}"),
    }
}

#[test]
fn the_device_sort_is_a_stable_sort_on_its_bits() {
    let Some(g) = gpu("the_device_sort_is_a_stable_sort_on_its_bits") else { return };
    let mut r = XorShift(0x5eed_5047);
    let sizes = [1usize, 255, 1023, 1024, 1025, 4095, 4096, 4097, 70_001, 1_500_000, 20_000_000];
    let cases: [(&str, std::ops::Range<u32>); 7] = [
        ("uniform", 0..32),
        ("uniform", 0..16),
        ("uniform", 8..24),
        ("equal", 0..32),
        ("descending", 0..32),
        ("three", 0..24),
        ("top byte", 0..32),
    ];
    for &n in &sizes {
        for (kind, bits) in &cases {
            if n == 20_000_000 && *kind != "uniform" {
                continue;
            }
            let keys = keys_of(kind, n, &mut r);
            let vals: Vec<u32> = (0..n as u32).collect();
            let (dk, dv) = g.sort_pairs(&keys, &vals, bits.clone()).unwrap();
            let m = mask(bits);
            let mut want = vals.clone();
            want.sort_by_key(|&i| keys[i as usize] & m);
            let bad = dv.iter().zip(&want).position(|(a, b)| a != b);
            assert!(bad.is_none(), "{kind} keys, n {n}, bits {bits:?}: first wrong position {bad:?}");
            let keys_ok = dk.iter().zip(&dv).all(|(&k, &v)| k == keys[v as usize]);
            assert!(keys_ok, "{kind} keys, n {n}, bits {bits:?}: a key left its value");
        }
        println!("n {n}: every case sorted stably");
    }
    assert_eq!(g.sort_pairs(&[], &[], 0..32).unwrap(), (vec![], vec![]));
    assert!(g.sort_pairs(&[1, 2], &[0], 0..32).is_err(), "lengths that disagree are refused");
    assert!(g.sort_pairs(&[1], &[0], 4..12).is_err(), "a range off the 8-bit digits is refused");
}
