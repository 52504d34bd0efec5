//! The batch manifest, plan and node stamps: bad manifests are refused naming the field; the
//! plan's nodes come in dependency order with their resources; a node runs once, is skipped
//! while its inputs and settings are unchanged, runs again when an input changes or an output
//! goes, never runs before its dependencies, and a failed or killed command leaves no stamp.

use pipeline::batch::manifest::Manifest;
use pipeline::batch::node::{exec, fresh, key, Outcome};
use pipeline::batch::plan::{build, Node, Plan, Resources};
use std::collections::BTreeMap;
use std::path::Path;

fn manifest(dir: &Path, text: &str) -> Result<Manifest, String> {
    let f = dir.join("m.toml");
    std::fs::write(&f, text).unwrap();
    Manifest::read(&f).map_err(|e| e.to_string())
}

#[test]
fn bad_manifests_name_the_problem() {
    let d = tempfile::tempdir().unwrap();
    let log = "[[log]]\nname = \"a\"\ninput = \"x.tfrecord\"\n";
    for (text, expect) in [
        ("", "no [[log]]"),
        (log, "no stage"),
        ("[[log]]\nname = \"a b\"\ninput = \"x\"\n[eval_cases]\n", "log[0].name `a b`"),
        (&format!("{log}{log}[eval_cases]\n"), "`a` is used twice"),
        ("[[log]]\nname = \"a\"\n[eval_cases]\n", "give `input` (to ingest) or `scene`"),
        ("[[log]]\nname = \"a\"\ninput = \"x\"\nscene = \"y\"\n[eval_cases]\n", "not both"),
        (&format!("{log}[eval_cases]\nshards = 0\n"), "shards = 0"),
        (&format!("{log}[run]\nbehaviors = [\"sudden_cut_in\"]\n"), "add a [train] stage"),
        (&format!("{log}[train]\n[run]\nbehaviors = [\"fly\"]\n"), "[run] behaviors"),
        (&format!("{log}[train]\ndevice = \"tpu\"\n"), "device `tpu`"),
        (&format!("{log}[train]\ncpus = 0\n"), "[train] cpus"),
        (&format!("{log}[eval_cases]\nshard = 4\n"), "unknown field `shard`"),
    ] {
        let e = manifest(d.path(), text).err().unwrap_or_else(|| panic!("accepted:\n{text}"));
        assert!(e.contains(expect), "{text}\n=> {e}");
        assert!(e.contains("m.toml"), "{e}");
    }
}

#[test]
fn the_plan_lists_nodes_after_their_dependencies() {
    let d = tempfile::tempdir().unwrap();
    let m = manifest(
        d.path(),
        "[[log]]\nname = \"a\"\ninput = [\"a1.tfrecord\", \"a2.tfrecord\"]\n[[log]]\nname = \"b\"\nscene = \"scenes/b\"\n\
         [priors]\n[train]\ndevice = \"cuda\"\niters = 100\n[eval_cases]\nshards = 3\nt0 = \"every:1s\"\n\
         [run]\nbehaviors = [\"sudden_cut_in\", \"sudden_braking\"]\n",
    )
    .unwrap();
    let p = build(&m, &d.path().join("m.toml"), &d.path().join("out")).unwrap();
    assert_eq!(p.stages, ["ingest", "priors", "train", "eval_cases", "tables", "run"]);
    let count = |s: &str| p.nodes.iter().filter(|n| n.stage == s).count();
    assert_eq!([count("ingest"), count("priors"), count("train"), count("eval_cases"), count("run")], [1, 2, 2, 3, 4]);
    let mut seen = std::collections::BTreeSet::new();
    for n in &p.nodes {
        assert!(n.deps.iter().all(|x| seen.contains(x)), "{} before its dependencies", n.id);
        assert!(seen.insert(n.id.clone()), "{} twice", n.id);
        assert!(n.inputs.iter().chain(&n.outputs).all(|x| x.is_absolute()), "{}", n.id);
    }
    let train = p.nodes.iter().find(|n| n.id == "train/a").unwrap();
    assert_eq!(train.resources, Resources { cpus: 4, gpus: 1, memory_gb: 16.0 });
    assert_eq!(train.deps, ["priors/a"]);
    assert!(train.args.windows(2).any(|w| w == ["--iters", "100"]));
    let shard = p.nodes.iter().find(|n| n.id == "eval_cases/2-of-3").unwrap();
    assert!(shard.args.windows(2).any(|w| w == ["--shard", "2/3"]));
    assert_eq!(shard.env["RAYON_NUM_THREADS"], "1");
    assert_eq!(shard.deps, ["ingest/a"], "b is an existing scene: nothing to wait for");
    assert_eq!(p.nodes.iter().find(|n| n.id == "tables").unwrap().deps.len(), 3);
    assert_eq!(p.nodes.iter().find(|n| n.id == "run/b/sudden_braking").unwrap().deps, ["train/b"]);
}

fn sh_node(id: &str, script: &str, input: &Path, output: &Path, deps: &[&str]) -> Node {
    Node {
        id: id.into(),
        stage: id.into(),
        index: 0,
        args: vec!["-c".into(), script.into()],
        env: BTreeMap::new(),
        inputs: vec![input.to_path_buf()],
        outputs: vec![output.to_path_buf()],
        deps: deps.iter().map(|s| s.to_string()).collect(),
        resources: Resources { cpus: 1, gpus: 0, memory_gb: 1.0 },
    }
}

#[test]
fn a_node_runs_once_until_an_input_or_output_changes() {
    let d = tempfile::tempdir().unwrap();
    let (input, output, count) = (d.path().join("in.txt"), d.path().join("out.txt"), d.path().join("count"));
    std::fs::write(&input, "1").unwrap();
    let script =
        format!("cat {i} > {o}; echo x >> {c}", i = input.display(), o = output.display(), c = count.display());
    let plan = Plan {
        format: "carla-gs-batch-plan".into(),
        version: 1,
        manifest: d.path().join("m.toml"),
        out: d.path().to_path_buf(),
        stages: vec!["a".into(), "b".into()],
        nodes: vec![
            sh_node("a", &script, &input, &output, &[]),
            sh_node("b", "exit 7", &output, &d.path().join("never"), &["a"]),
        ],
    };
    let sh = Path::new("/bin/sh");
    let runs = || std::fs::read_to_string(&count).map_or(0, |s| s.lines().count());
    // b needs a: refused before a has run.
    let e = exec(&plan, &plan.nodes[1], sh).unwrap_err().to_string();
    assert!(e.contains("dependency a has not finished"), "{e}");
    assert!(matches!(exec(&plan, &plan.nodes[0], sh).unwrap(), Outcome::Ran { exit_code: 0, .. }));
    assert!(matches!(exec(&plan, &plan.nodes[0], sh).unwrap(), Outcome::Skipped(_)));
    assert_eq!(runs(), 1);
    // A changed input (size or time) runs it again; so does a removed output.
    std::fs::write(&input, "22").unwrap();
    assert!(fresh(&plan, &plan.nodes[0], &key(&plan.nodes[0]).unwrap()).is_none());
    assert!(matches!(exec(&plan, &plan.nodes[0], sh).unwrap(), Outcome::Ran { .. }));
    std::fs::remove_file(&output).unwrap();
    assert!(matches!(exec(&plan, &plan.nodes[0], sh).unwrap(), Outcome::Ran { .. }));
    assert!(matches!(exec(&plan, &plan.nodes[0], sh).unwrap(), Outcome::Skipped(_)));
    assert_eq!(runs(), 3);
    // A failing command is reported with its code and leaves no stamp: it runs again next time.
    assert!(matches!(exec(&plan, &plan.nodes[1], sh).unwrap(), Outcome::Ran { exit_code: 7, .. }));
    assert!(matches!(exec(&plan, &plan.nodes[1], sh).unwrap(), Outcome::Ran { exit_code: 7, .. }));
    // A command that exits 0 without its outputs is an error, not a finished node.
    let mut liar = plan.nodes[1].clone();
    liar.args = vec!["-c".into(), "exit 0".into()];
    assert!(exec(&plan, &liar, sh).unwrap_err().to_string().contains("without writing its outputs"));
}
