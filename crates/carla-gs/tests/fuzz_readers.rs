//! Issue 28 item 6: property tests over every reader (docs/fuzz.md). Each target starts from a
//! small valid input, applies proptest-generated mutations (bit flips, truncation, inserted
//! bytes, and in text formats numbers replaced by huge, negative, NaN or infinite values and
//! strings by values of other types), and calls the library reader inside `catch_unwind`. The
//! property: no panic, no single allocation past [`ALLOC_BUDGET`], and the reader returns Ok or
//! a clean Err. `CARLA_GS_FUZZ_CASES` sets the cases per target (default 64); each target prints
//! `fuzz <target>: <cases> cases, <ok> ok, <err> refused`. The file formats are in
//! `fuzz_readers/files.rs`, the ingest sources in `fuzz_readers/ingest.rs`, the batch manifest,
//! plan, shard record and case file in `fuzz_readers/batch.rs`.

#[path = "fuzz_readers/batch.rs"]
mod batch;
mod cli_support;
#[path = "fuzz_readers/files.rs"]
mod files;
#[path = "fuzz_readers/ingest.rs"]
mod ingest;

use proptest::prelude::*;
use proptest::sample::Index;
use proptest::test_runner::{Config, TestCaseError, TestRunner};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicUsize, Ordering};

/// The largest single allocation a reader may ask for on these small inputs (1 GiB). A larger
/// request is refused (null: fallible allocations fail cleanly, the others abort the test) and
/// recorded, and the case fails.
const ALLOC_BUDGET: usize = 1 << 30;
static OVER_BUDGET: AtomicUsize = AtomicUsize::new(0);

struct Budgeted;

unsafe impl GlobalAlloc for Budgeted {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        if l.size() > ALLOC_BUDGET {
            OVER_BUDGET.fetch_max(l.size(), Ordering::SeqCst);
            return std::ptr::null_mut();
        }
        System.alloc(l)
    }
    unsafe fn alloc_zeroed(&self, l: Layout) -> *mut u8 {
        if l.size() > ALLOC_BUDGET {
            OVER_BUDGET.fetch_max(l.size(), Ordering::SeqCst);
            return std::ptr::null_mut();
        }
        System.alloc_zeroed(l)
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        System.dealloc(p, l)
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, new_size: usize) -> *mut u8 {
        if new_size > ALLOC_BUDGET {
            OVER_BUDGET.fetch_max(new_size, Ordering::SeqCst);
            return std::ptr::null_mut();
        }
        System.realloc(p, l, new_size)
    }
}

#[global_allocator]
static GLOBAL: Budgeted = Budgeted;

/// Cases per target: `CARLA_GS_FUZZ_CASES`, else 64.
fn cases() -> u32 {
    std::env::var("CARLA_GS_FUZZ_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(64)
}

/// Values a number in a text format is replaced by.
const NUMBERS: [&str; 12] = [
    "1e300",
    "-1e300",
    "-1",
    "0",
    "-0",
    "NaN",
    "inf",
    "-inf",
    "9223372036854775808",
    "18446744073709551616",
    "1e999",
    "4294967296",
];
/// Values a string in a text format is replaced by (other JSON/TOML types).
const RETYPED: [&str; 8] = ["null", "[]", "{}", "true", "-1", "1e300", "\"\"", "[[[[[[[[[[[[[[[[]]]]]]]]]]]]]]]]"];

#[derive(Clone, Debug)]
enum Mutation {
    Flip(Index, u8),
    Truncate(Index),
    Insert(Index, Vec<u8>),
    Number(Index, usize),
    Retype(Index, usize),
}

fn mutation(text: bool) -> BoxedStrategy<Mutation> {
    let binary = prop_oneof![
        (any::<Index>(), any::<u8>()).prop_map(|(i, b)| Mutation::Flip(i, b)),
        any::<Index>().prop_map(Mutation::Truncate),
        (any::<Index>(), prop::collection::vec(any::<u8>(), 1..16)).prop_map(|(i, v)| Mutation::Insert(i, v)),
    ];
    if !text {
        return binary.boxed();
    }
    prop_oneof![
        2 => binary,
        3 => (any::<Index>(), 0..NUMBERS.len()).prop_map(|(i, k)| Mutation::Number(i, k)),
        2 => (any::<Index>(), 0..RETYPED.len()).prop_map(|(i, k)| Mutation::Retype(i, k)),
    ]
    .boxed()
}

/// Byte spans of numbers (not inside identifiers) in `b`.
fn number_spans(b: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let prev_ok = i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b"_.\"/".contains(&b[i - 1]));
        let starts = b[i].is_ascii_digit() || (b[i] == b'-' && b.get(i + 1).is_some_and(u8::is_ascii_digit));
        if prev_ok && starts {
            let s = i;
            i += 1;
            while i < b.len() && (b[i].is_ascii_digit() || b".eE+-".contains(&b[i])) {
                i += 1;
            }
            out.push((s, i));
        } else {
            i += 1;
        }
    }
    out
}

/// Byte spans of double-quoted strings in `b`.
fn string_spans(b: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'"' {
            let s = i;
            i += 1;
            while i < b.len() && b[i] != b'"' {
                i += if b[i] == b'\\' { 2 } else { 1 };
            }
            i += 1;
            out.push((s, i.min(b.len())));
        } else {
            i += 1;
        }
    }
    out
}

fn replace_span(b: &mut Vec<u8>, spans: Vec<(usize, usize)>, i: &Index, with: &str) {
    if !spans.is_empty() {
        let (s, e) = spans[i.index(spans.len())];
        b.splice(s..e, with.bytes());
    }
}

fn apply(b: &mut Vec<u8>, m: &Mutation) {
    match m {
        Mutation::Flip(i, bit) if !b.is_empty() => {
            let k = i.index(b.len());
            b[k] ^= 1 << (bit % 8);
        }
        Mutation::Flip(..) => {}
        Mutation::Truncate(i) => b.truncate(i.index(b.len() + 1)),
        Mutation::Insert(i, v) => {
            let k = i.index(b.len() + 1);
            b.splice(k..k, v.iter().copied());
        }
        Mutation::Number(i, k) => replace_span(b, number_spans(b), i, NUMBERS[*k]),
        Mutation::Retype(i, k) => replace_span(b, string_spans(b), i, RETYPED[*k]),
    }
}

fn panic_message(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<String>().cloned().or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string())).unwrap_or_default()
}

/// Fuzzes `read` over `base`, a set of named files of which each case mutates one (`text`: the
/// files are text, so numbers and strings are replaced too). The unmutated set must be read.
fn fuzz_files(
    target: &str,
    base: &[(String, Vec<u8>)],
    text: bool,
    read: impl Fn(&[(String, Vec<u8>)]) -> Result<(), String>,
) {
    if let Err(e) = read(base) {
        panic!("fuzz {target}: the unmutated input is refused: {e}");
    }
    let (ok, refused) = (Cell::new(0u32), Cell::new(0u32));
    let mut runner = TestRunner::new(Config { cases: cases(), failure_persistence: None, ..Config::default() });
    let strategy = (any::<Index>(), prop::collection::vec(mutation(text), 1..4));
    let result = runner.run(&strategy, |(which, muts)| {
        let mut files = base.to_vec();
        let k = which.index(files.len());
        for m in &muts {
            apply(&mut files[k].1, m);
        }
        match catch_unwind(AssertUnwindSafe(|| read(&files))) {
            Ok(Ok(())) => ok.set(ok.get() + 1),
            Ok(Err(_)) => refused.set(refused.get() + 1),
            Err(p) => return Err(TestCaseError::fail(format!("{} panicked: {}", files[k].0, panic_message(&*p)))),
        }
        let over = OVER_BUDGET.swap(0, Ordering::SeqCst);
        prop_assert!(over == 0, "{}: an allocation of {over} bytes (budget {ALLOC_BUDGET})", files[k].0);
        Ok(())
    });
    cli_support::fuzz_log(&format!(
        "fuzz {target}: {} cases, {} ok, {} refused",
        ok.get() + refused.get(),
        ok.get(),
        refused.get()
    ));
    if let Err(e) = result {
        panic!("fuzz {target}: {e}");
    }
}

/// [`fuzz_files`] over one file.
fn fuzz(target: &str, base: &[u8], text: bool, read: impl Fn(&[u8]) -> Result<(), String>) {
    fuzz_files(target, &[(target.to_string(), base.to_vec())], text, |f| read(&f[0].1));
}

/// `Err(e.to_string())` of any error.
fn clean<T, E: std::fmt::Display>(r: Result<T, E>) -> Result<(), String> {
    r.map(|_| ()).map_err(|e| e.to_string())
}

#[test]
fn mutations_change_numbers_and_strings() {
    let b = br#"{"a": 1.5, "b": "x", "c": [-2, 3e4], "CAM1": "./r_2"}"#;
    let nums: Vec<&[u8]> = number_spans(b).into_iter().map(|(s, e)| &b[s..e]).collect();
    assert_eq!(nums, [&b"1.5"[..], b"-2", b"3e4"]);
    let strs: Vec<&[u8]> = string_spans(b).into_iter().map(|(s, e)| &b[s..e]).collect();
    assert_eq!(strs, [&b"\"a\""[..], b"\"b\"", b"\"x\"", b"\"c\"", b"\"CAM1\"", b"\"./r_2\""]);
}
