//! Plots need no font of the machine: the embedded DejaVu Sans draws their text (issue 56 A).

#[test]
fn plots_are_drawn_with_the_embedded_font() {
    // The system's fonts are never looked up; only CARLA_GS_FONT could replace the embedded one.
    assert!(std::env::var_os("CARLA_GS_FONT").is_none(), "run this test without CARLA_GS_FONT");
    assert_eq!(cases::plots::ensure_font(), Ok(cases::plots::FontOrigin::Embedded));
    let tmp = tempfile::tempdir().unwrap();
    let png = tmp.path().join("table1.png");
    cases::plots::table1_bars(&png, &[]).unwrap();
    let bytes = std::fs::read(&png).unwrap();
    assert!(bytes.starts_with(b"\x89PNG"), "not a PNG");
}
