#!/usr/bin/env python3
"""Ray driver of splat2tiles' sharded conversion: plan, one Ray task per part, merge.

    python3 tools/splat2tiles_ray.py INPUT -o OUT --parts N --work DIR [-- CONVERT OPTIONS]

Every step runs the `splat2tiles` binary (on PATH of every node, or --binary) as a Ray task:
`convert INPUT --plan` (one cheap pass), then per part `convert --part I --phase samples`
(the leaf statistics the default leaf radius needs; skipped when the plan does not need them),
`convert --part I` (the part's tiles), and `merge`. Each step writes its output atomically
(staging folder renamed into place) and is re-runnable, so a task that dies is simply run
again by Ray (`max_retries`). INPUT, DIR and OUT must be paths every node sees (shared
storage). `ray.init()` starts a local cluster; with RAY_ADDRESS set it joins that cluster.
README.md "Converting on a cluster" has the cluster and KubeRay recipes.
"""

import argparse
import json
import os
import signal
import subprocess
import sys
import time

# Test hook: the part task whose (phase:part) equals this value kills its splat2tiles process
# and then itself (SIGKILL, as when a node dies) on its first attempt; a marker file in the
# work folder remembers that attempt, so Ray's retry runs the part normally.
KILL_ENV = "SPLAT2TILES_RAY_KILL"


def run_step(argv, env=None):
    """Runs one splat2tiles step with --json; returns its JSON report (raises on failure)."""
    t0 = time.time()
    p = subprocess.run(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(argv)} exited {p.returncode}: {p.stderr.strip()}")
    report = json.loads(p.stdout.strip().splitlines()[-1])
    report["wallSeconds"] = time.time() - t0
    return report


def _env(threads):
    env = dict(os.environ)
    if threads:
        env["RAYON_NUM_THREADS"] = str(threads)
    return env


def part_step(binary, input_path, plan, part, phase, out, samples, memory_limit, threads, work):
    """One part (one phase) of the plan; the body of the Ray part task."""
    argv = [binary, "convert", input_path, "--plan", plan, "--part", str(part),
            "--phase", phase, "-o", out, "--json", "--quiet"]
    if samples:
        argv += ["--samples", *samples]
    if memory_limit:
        argv += ["--memory-limit", memory_limit]
    env = _env(threads)
    kill = os.environ.get(KILL_ENV)
    marker = os.path.join(work, f".killed-{phase}-{part}")
    if kill == f"{phase}:{part}" and not os.path.exists(marker):
        open(marker, "w").close()
        # Start the step, let it write for a while, then kill it and this worker outright.
        child = subprocess.Popen(argv, env=env,
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        deadline = time.time() + 60
        parent = os.path.dirname(os.path.abspath(out)) or "."
        name = os.path.basename(out)
        # Killed once its staging folder holds something (spill files: it is writing).
        while time.time() < deadline and child.poll() is None:
            staged = [f for f in os.listdir(parent) if f.startswith(f".{name}.s2t-tmp-")]
            if staged and os.listdir(os.path.join(parent, staged[0])):
                break
            time.sleep(0.005)
        child.kill()
        child.wait()
        os.kill(os.getpid(), signal.SIGKILL)
    report = run_step(argv, env)
    report["host"] = os.uname().nodename
    report["phase"] = phase
    return report


def plan_step(binary, input_path, plan, parts, convert_args, memory_limit, threads):
    argv = [binary, "convert", input_path, "--plan", plan, "--parts", str(parts), "--json",
            "--quiet", *convert_args]
    if memory_limit:
        argv += ["--memory-limit", memory_limit]
    return run_step(argv, _env(threads))


def merge_step(binary, plan, parts, out, memory_limit, threads):
    argv = [binary, "merge", plan, *parts, "-o", out, "--json", "--quiet"]
    if memory_limit:
        argv += ["--memory-limit", memory_limit]
    return run_step(argv, _env(threads))


def convert(input_path, output, parts, work, binary="splat2tiles", convert_args=(),
            memory_limit=None, retries=3, cpus_per_task=1, num_cpus=None):
    """Converts `input_path` into the tileset folder `output` in `parts` parts on Ray; the plan
    and part folders go under `work`. Returns the per-step reports (times, peak RSS, bytes)."""
    import ray

    if not ray.is_initialized():
        if os.environ.get("RAY_ADDRESS"):
            ray.init(address=os.environ["RAY_ADDRESS"])
        else:
            ray.init(num_cpus=num_cpus, include_dashboard=False)
    input_path = os.path.abspath(input_path)
    output = os.path.abspath(output)
    work = os.path.abspath(work)
    os.makedirs(work, exist_ok=True)
    plan = os.path.join(work, "plan.json")
    opts = dict(num_cpus=cpus_per_task, max_retries=retries, retry_exceptions=True)
    threads = cpus_per_task
    t0 = time.time()
    plan_task = ray.remote(plan_step).options(**opts)
    plan_report = ray.get(plan_task.remote(binary, input_path, plan, parts, list(convert_args),
                                           memory_limit, threads))
    with open(plan) as f:
        plan_json = json.load(f)
    needs_samples = plan_json["options"]["lod"] and plan_json["options"]["lodRadius"] is None
    part_task = ray.remote(part_step).options(**opts)
    samples = []
    sample_reports = []
    t1 = time.time()
    if needs_samples:
        samples = [os.path.join(work, f"samples-{i}") for i in range(parts)]
        sample_reports = ray.get([
            part_task.remote(binary, input_path, plan, i, "samples", samples[i], [],
                             memory_limit, threads, work)
            for i in range(parts)
        ])
    t2 = time.time()
    part_dirs = [os.path.join(work, f"part-{i}") for i in range(parts)]
    build_reports = ray.get([
        part_task.remote(binary, input_path, plan, i, "build", part_dirs[i], samples,
                         memory_limit, threads, work)
        for i in range(parts)
    ])
    t3 = time.time()
    merge_task = ray.remote(merge_step).options(**opts)
    merge_report = ray.get(merge_task.remote(binary, plan, part_dirs, output, memory_limit,
                                             threads))
    t4 = time.time()
    return {
        "parts": parts,
        "plan": plan_report,
        "samples": sample_reports,
        "build": build_reports,
        "merge": merge_report,
        "seconds": {"plan": t1 - t0, "samples": t2 - t1, "build": t3 - t2, "merge": t4 - t3,
                    "total": t4 - t0},
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 epilog="after --: convert options for the plan")
    ap.add_argument("input", help="input scene (a path every node can read)")
    ap.add_argument("-o", "--output", required=True, help="output tileset folder")
    ap.add_argument("--parts", type=int, required=True, help="number of parts (Ray tasks)")
    ap.add_argument("--work", required=True, help="folder for the plan and the parts (shared)")
    ap.add_argument("--binary", default="splat2tiles", help="splat2tiles on every node")
    ap.add_argument("--memory-limit", help="--memory-limit of every step, e.g. 4GiB")
    ap.add_argument("--retries", type=int, default=3, help="Ray max_retries per task")
    ap.add_argument("--cpus-per-task", type=int, default=1,
                    help="Ray CPUs per task (also the step's worker threads)")
    ap.add_argument("--num-cpus", type=int, help="CPUs of the local cluster (no RAY_ADDRESS)")
    ap.add_argument("--json", action="store_true", help="print the step reports as JSON")
    argv = list(sys.argv[1:] if argv is None else argv)
    # After `--`: convert options for the plan (e.g. -- --max-splats 16384).
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    a = ap.parse_args(argv[:argv.index("--")] if "--" in argv else argv)
    r = convert(a.input, a.output, a.parts, a.work, a.binary, extra, a.memory_limit,
                a.retries, a.cpus_per_task, a.num_cpus)
    if a.json:
        print(json.dumps(r))
    else:
        s = r["seconds"]
        print(f"converted {a.input} into {a.output} in {a.parts} parts: plan {s['plan']:.1f} s, "
              f"samples {s['samples']:.1f} s, parts {s['build']:.1f} s, merge {s['merge']:.1f} s, "
              f"total {s['total']:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
