//! The case search's second window on a real log (PandaSet 002): a braking lead's plan ends when it
//! stands, before the logged ego closes in, so no attempt over the plan's own end succeeds; the
//! demo's request then searches the tables' window (5 s from t0, braking to rest after the plan)
//! and finds a case that is valid, hits its zone and succeeds. Every attempt of both passes is
//! reported with its window, and the second pass runs only because the first found nothing.

use cases::spec::{AgentName, T0Spec};
use cases::window::{Horizon, Window};
use indicatif::ProgressBar;
use pipeline::case::{rendered_window, select_case, CaseRequest, T0Choice};
use scene::Behavior;

fn request(behavior: Behavior, fallback: Option<Window>) -> CaseRequest {
    CaseRequest {
        behavior,
        agent: AgentName::Planner,
        adversary: None,
        zone: None,
        ttc_s: None,
        insert: Default::default(),
        seed: 0,
        seeds_per_t0: 3,
        refine_rounds: 3,
        window: rendered_window(),
        fallback_window: fallback,
    }
}

#[test]
fn braking_on_pandaset_succeeds_over_the_tables_window_after_the_plans_own_end_fails() {
    let Some(src) = ingest::shared::data_path("pandaset/002") else { return };
    let scene = ingest::read_scenes(&[src], ingest::Expect::Auto, &ProgressBar::hidden()).unwrap().remove(0);
    let search = T0Choice::Search(T0Spec::Every(0.5));
    let good = |a: &pipeline::case::Attempt| a.valid && a.zone_hit && a.success;

    let plan_only = select_case(&scene, &request(Behavior::SuddenBraking, None), &search, None);
    assert!(!plan_only.attempts.is_empty() && plan_only.attempts.iter().all(|a| a.window == rendered_window()));
    assert!(
        !plan_only.attempts.iter().any(good),
        "a braking case succeeded over the plan's own end: {:?}",
        plan_only.attempts
    );

    let tables = Window::default();
    assert_eq!(tables.horizon, Horizon::Seconds(5.0));
    let both = select_case(&scene, &request(Behavior::SuddenBraking, Some(tables)), &search, None);
    let n = plan_only.attempts.len();
    assert_eq!(both.attempts[..n], plan_only.attempts[..], "the first pass is the plan-only search");
    assert!(both.attempts[n..].iter().all(|a| a.window == tables) && both.attempts.len() > n);
    let last = both.attempts.last().unwrap();
    assert!(good(last), "the search stops at the first good case: {last:?}");
    assert!(!both.attempts[n..both.attempts.len() - 1].iter().any(good));
    let (result, _, window) = both.chosen.expect("a case");
    assert_eq!(window, tables);
    let m = &result.best().unwrap().metrics;
    assert!(m.validity.valid && m.zone_hit && m.success_center && m.min_ttc_center_s < 1.0, "{m:?}");
}

#[test]
fn the_second_window_is_not_searched_once_the_first_succeeds() {
    let Some(src) = ingest::shared::data_path("pandaset/002") else { return };
    let scene = ingest::read_scenes(&[src], ingest::Expect::Auto, &ProgressBar::hidden()).unwrap().remove(0);
    // An oncoming drift succeeds over its plan's own end at the first t0s searched.
    let req = request(Behavior::OpposingDrift, Some(Window::default()));
    let sel = select_case(&scene, &req, &T0Choice::Search(T0Spec::Every(0.5)), None);
    assert!(sel.attempts.iter().all(|a| a.window == rendered_window()), "{:?}", sel.attempts);
    let last = sel.attempts.last().unwrap();
    assert!(last.valid && last.zone_hit && last.success, "{last:?}");
    assert_eq!(sel.chosen.expect("a case").2, rendered_window());
}

/// `run --insert always` reaches the case search (it was dropped between the command's flags and
/// the search, which then chose a logged car): on PandaSet 002 the sudden cut-in at t0 = 4 s is
/// made with a logged car, and with `always` by an inserted car (at some t0 of the log), marked
/// in the plan.
#[test]
fn insert_always_reaches_the_search_on_pandaset() {
    let Some(src) = ingest::shared::data_path("pandaset/002") else { return };
    let scene = ingest::read_scenes(&[src], ingest::Expect::Auto, &ProgressBar::hidden()).unwrap().remove(0);
    let at = T0Choice::At(4.0);
    let mut req = request(Behavior::SuddenCutIn, None);
    let logged = select_case(&scene, &req, &at, None);
    let (result, _, _) = logged.chosen.expect("a logged cut-in at 4 s");
    assert!(result.best().unwrap().plan.inserted.is_none());
    req.insert = reason::insert::InsertMode::Always;
    let inserted = select_case(&scene, &req, &T0Choice::Search(T0Spec::Every(0.5)), None);
    let (result, _, _) = inserted.chosen.unwrap_or_else(|| panic!("an inserted cut-in: {:?}", inserted.attempts));
    eprintln!("inserted cut-in at t0 {:.1} s: {:?}", result.spec.t0_s, result.best().unwrap().metrics.min_ttc_center_s);
    let plan = &result.best().unwrap().plan;
    assert!(plan.inserted.is_some() && plan.adversary_track.starts_with("inserted-"), "{}", plan.adversary_track);
}
