#!/usr/bin/env python3
"""Run a carla-gs batch plan on Ray, or write it as a Slurm submission script.

The plan (`carla-gs batch plan <manifest.toml> --out <dir>` writes <dir>/plan.json) is a graph
of plain carla-gs commands. This driver schedules nothing itself: it hands Ray one task per node,
with the node's CPU cores, GPUs and memory, its dependencies as the task's arguments (Ray starts
a task when the tasks it needs have finished) and a bounded number of retries; each task runs
`carla-gs batch exec <plan> <node>`, which skips a node that already finished from the same
inputs and settings. The merged tables are the plan's `tables` node.

    # on a laptop (a local Ray instance with this machine's cores)
    tools/batch_ray.py out/plan.json --binary target/release/carla-gs
    # on a cluster (every worker sees the plan's paths on a shared file system)
    RAY_ADDRESS=ray://head:10001 tools/batch_ray.py out/plan.json --binary /shared/bin/carla-gs
    # a Slurm cluster: one `sbatch --array` per stage, chained with afterok
    tools/batch_ray.py out/plan.json --binary /shared/bin/carla-gs --slurm out/submit.sh

Ray comes from PyPI; tools/setup.sh installs it into $XDG_CACHE_HOME/carla-gs/ray-venv (use that
venv's python). --slurm needs no Ray. docs/batch.md has the whole story.
"""

import argparse
import json
import os
import shlex
import subprocess
import sys
import time
from pathlib import Path

# Exit codes of `carla-gs batch exec`: 0 done (or skipped), 3 no case possible (final).
DONE, NO_CASE = 0, 3


def load_plan(path):
    plan = json.loads(Path(path).read_text())
    if plan.get("format") != "carla-gs-batch-plan" or plan.get("version") != 1:
        sys.exit(f"{path}: not a carla-gs batch plan (format carla-gs-batch-plan v1)")
    ids = set()
    for n in plan["nodes"]:
        missing = [d for d in n["deps"] if d not in ids]
        if missing:
            sys.exit(f"{path}: node {n['id']} needs {missing} before it: not in dependency order")
        ids.add(n["id"])
    return plan


def tail(text, lines=15):
    return "\n".join(text.strip().splitlines()[-lines:])


class NodeFailed(Exception):
    pass


def run_node(binary, plan_path, node_id, *deps):
    """One node, in a Ray worker: `carla-gs batch exec`; raises on failure so Ray retries it."""
    for d in deps:
        if d["exit_code"] != DONE:
            return {"id": node_id, "exit_code": None, "outcome": f"not run: {d['id']} ended with exit {d['exit_code']}"}
    start = time.time()
    p = subprocess.run([binary, "batch", "exec", plan_path, node_id], capture_output=True, text=True)
    seconds = time.time() - start
    if p.returncode not in (DONE, NO_CASE):
        raise NodeFailed(f"{node_id}: exit {p.returncode}\n{tail(p.stderr or p.stdout)}")
    last = (p.stdout.strip().splitlines() or [""])[-1]
    outcome = "skipped" if last.startswith("skip ") else ("no case" if p.returncode == NO_CASE else "ran")
    return {"id": node_id, "exit_code": p.returncode, "outcome": outcome, "seconds": seconds, "host": os.uname().nodename}


def run_ray(plan, plan_path, binary, retries, num_cpus, num_gpus):
    import ray

    if os.environ.get("RAY_ADDRESS"):
        ray.init(log_to_driver=False)
    else:
        ray.init(num_cpus=num_cpus, num_gpus=num_gpus, include_dashboard=False, log_to_driver=False)
    total = ray.cluster_resources()
    remote = ray.remote(run_node)
    refs, by_ref = {}, {}
    for n in plan["nodes"]:
        r = n["resources"]
        if r["gpus"] > total.get("GPU", 0):
            sys.exit(f"{n['id']} needs {r['gpus']} GPU(s); the Ray cluster has {total.get('GPU', 0)}")
        # A request above the whole cluster's would wait forever: capped, and said so.
        cpus = min(r["cpus"], total.get("CPU", 1))
        memory = min(int(r["memory_gb"] * 2**30), int(total.get("memory", 2**62)))
        if cpus < r["cpus"]:
            print(f"note: {n['id']} asks {r['cpus']} CPUs; the cluster has {cpus:g}", file=sys.stderr)
        opts = dict(
            num_cpus=cpus,
            num_gpus=r["gpus"],
            memory=memory,
            max_retries=retries,
            retry_exceptions=True,
            name=n["id"],
            runtime_env={"env_vars": {k: str(v) for k, v in n["env"].items()}},
        )
        ref = remote.options(**opts).remote(binary, plan_path, n["id"], *[refs[d] for d in n["deps"]])
        refs[n["id"]] = ref
        by_ref[ref] = n["id"]
    pending, results, start = list(refs.values()), {}, time.time()
    while pending:
        done, pending = ray.wait(pending, num_returns=1)
        node_id = by_ref[done[0]]
        try:
            res = ray.get(done[0])
        except Exception as e:  # the node failed after its retries (or a dependency did)
            msg = str(e).strip().splitlines()
            res = {"id": node_id, "exit_code": None, "outcome": "failed: " + (msg[-1] if msg else repr(e))}
        results[node_id] = res
        secs = f" {res['seconds']:.1f} s" if "seconds" in res else ""
        print(f"[{len(results)}/{len(refs)} {time.time() - start:6.1f} s] {node_id}: {res['outcome']}{secs}", flush=True)
    ray.shutdown()
    return results, time.time() - start


def write_slurm(plan, plan_path, binary, retries, script):
    """One `sbatch --array` per stage (array index = the node's index in its stage, e.g. the
    eval-cases shard I of N), each after the stages its nodes need (afterok)."""
    stage_of = {n["id"]: n["stage"] for n in plan["nodes"]}
    lines = [
        "#!/usr/bin/env bash",
        "# Submits the carla-gs batch plan below to Slurm: one array job per stage, each task one",
        "# node (`carla-gs batch exec --stage S --index $SLURM_ARRAY_TASK_ID`), retried up to",
        f"# {retries} times, stages chained with afterok. Written by tools/batch_ray.py --slurm.",
        "set -euo pipefail",
        f"PLAN={shlex.quote(str(Path(plan_path).resolve()))}",
        f"BIN={shlex.quote(binary)}",
        f"TRIES={retries + 1}",
        f"LOGS={shlex.quote(str(Path(plan['out']) / 'slurm-logs'))}",
        'mkdir -p "$LOGS"',
        "export PLAN BIN TRIES",
        "",
    ]
    # The task body: exit 0 done, 3 no case (final); anything else is retried.
    body = (
        'for t in $(seq 1 $TRIES); do "$BIN" batch exec "$PLAN" --stage {stage} --index $SLURM_ARRAY_TASK_ID; '
        "rc=$?; if [ $rc -eq 0 ] || [ $rc -eq 3 ]; then exit 0; fi; done; exit $rc"
    )
    for stage in plan["stages"]:
        nodes = [n for n in plan["nodes"] if n["stage"] == stage]
        cpus = max(n["resources"]["cpus"] for n in nodes)
        gpus = max(n["resources"]["gpus"] for n in nodes)
        mem = max(n["resources"]["memory_gb"] for n in nodes)
        after = sorted({stage_of[d] for n in nodes for d in n["deps"]}, key=plan["stages"].index)
        env = nodes[0]["env"]
        opts = [
            "--parsable",
            f"--array=0-{len(nodes) - 1}",
            f"--job-name=cgs-{stage}",
            f"--cpus-per-task={cpus}",
            f"--mem={int(mem * 1024)}M",
            f'--output="$LOGS/{stage}-%a.out"',
        ]
        if gpus:
            opts.append(f"--gres=gpu:{gpus}")
        if after:
            opts.append("--dependency=afterok:" + ":".join(f"${{JOB_{s.upper()}}}" for s in after))
        exports = " ".join(f"{k}={shlex.quote(str(v))}" for k, v in env.items())
        wrap = body.format(stage=stage)
        if exports:
            wrap = f"export {exports}; {wrap}"
        lines.append(f"# {stage}: {len(nodes)} node(s), {cpus} CPU(s), {gpus} GPU(s), {mem:g} GB each")
        # --parsable prints "id" or "id;cluster": afterok takes the id.
        lines.append(f"JOB_{stage.upper()}=$(sbatch {' '.join(opts)} --wrap {shlex.quote(wrap)} | cut -d';' -f1)")
        lines.append(f'echo "{stage}: job $JOB_{stage.upper()}"')
    Path(script).write_text("\n".join(lines) + "\n")
    os.chmod(script, 0o755)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("plan", help="plan.json from `carla-gs batch plan`")
    ap.add_argument("--binary", default="carla-gs", help="the carla-gs binary every worker runs")
    ap.add_argument("--retries", type=int, default=2, help="retries of a failed node (default 2)")
    ap.add_argument("--num-cpus", type=int, help="local Ray instance: CPUs (default: all)")
    ap.add_argument("--num-gpus", type=int, help="local Ray instance: GPUs (default: all)")
    ap.add_argument("--slurm", metavar="SCRIPT", help="write an sbatch script instead of running")
    a = ap.parse_args()
    if not 0 <= a.retries <= 100:
        sys.exit("--retries: expected 0 to 100")
    plan = load_plan(a.plan)
    binary = str(Path(a.binary).resolve()) if os.sep in a.binary else a.binary
    plan_path = str(Path(a.plan).resolve())
    if a.slurm:
        write_slurm(plan, plan_path, binary, a.retries, a.slurm)
        print(f"wrote {a.slurm}: {len(plan['stages'])} array jobs ({', '.join(plan['stages'])}); run it on the login node")
        return 0
    results, wall = run_ray(plan, plan_path, binary, a.retries, a.num_cpus, a.num_gpus)
    summary = {"plan": plan_path, "wall_s": wall, "nodes": [results[n["id"]] for n in plan["nodes"]]}
    out = Path(plan["out"]) / ".batch" / "ray-summary.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(summary, indent=2) + "\n")
    counts = {}
    for r in summary["nodes"]:
        key = r["outcome"].split(":")[0]
        counts[key] = counts.get(key, 0) + 1
    print(f"{len(results)} nodes in {wall:.1f} s: " + ", ".join(f"{v} {k}" for k, v in sorted(counts.items())))
    tables = [n for n in plan["nodes"] if n["stage"] == "tables"]
    if tables and results[tables[0]["id"]]["exit_code"] == DONE:
        print(f"merged tables: {Path(tables[0]['outputs'][0]).parent}")
    print(f"per node: {out}")
    failed = [r for r in summary["nodes"] if r["exit_code"] is None]
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
