#!/usr/bin/env python3
"""Ray driver of splat2tiles' sharded conversion: plan, one Ray task per part, merge.

    python3 tools/splat2tiles_ray.py INPUT -o OUT --parts N --work DIR [-- CONVERT OPTIONS]

Every step runs the `splat2tiles` binary (on PATH of every node, or --binary) as a Ray task:
`convert INPUT --plan` (two passes over the input), `convert INPUT --plan --route DIR
--route-chunk C --route-chunks K` (K tasks that together read the input once and write each
part's splats to its own files; one task for inputs read whole, such as SPZ, or with NaN/Inf
splats; --route-chunks 0 skips routing and every part reads the whole input), then per part
`convert --part I --phase samples` (the leaf statistics the default leaf radius needs; skipped
when the plan does not need them), `convert --part I` (the part's tiles), and `merge`.
--part-resources pins the tasks of part I (and routing chunk I) to nodes holding the custom
Ray resource NAMES[I % len(NAMES)]. Each step writes its output atomically
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

# Test hook: the part task whose (phase:part) equals this value (in the driver's environment;
# passed to the tasks, whose workers a running cluster started without it) kills its
# splat2tiles process and then itself (SIGKILL, as when a node dies) on its first attempt; a
# marker file in the work folder remembers that attempt, so Ray's retry runs the part normally.
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


def _node_id():
    """The Ray node running this task (None outside Ray)."""
    try:
        import ray
        return ray.get_runtime_context().get_node_id()
    except Exception:  # noqa: BLE001 - outside a Ray task
        return None


def part_step(binary, input_path, plan, part, phase, out, samples, memory_limit, threads, work,
              route=None, kill=None):
    """One part (one phase) of the plan; the body of the Ray part task."""
    argv = [binary, "convert", input_path, "--plan", plan, "--part", str(part),
            "--phase", phase, "-o", out, "--json", "--quiet"]
    if samples:
        argv += ["--samples", *samples]
    if route:
        argv += ["--route", route]
    if memory_limit:
        argv += ["--memory-limit", memory_limit]
    env = _env(threads)
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
        # The marker says whether the step was still running when killed (mid-part).
        with open(marker, "w") as f:
            f.write("running" if child.poll() is None else "finished")
        child.kill()
        child.wait()
        os.kill(os.getpid(), signal.SIGKILL)
    report = run_step(argv, env)
    report["host"] = os.uname().nodename
    report["node"] = _node_id()
    report["phase"] = phase
    # A first attempt killed by the test hook left its marker: this attempt is Ray's retry.
    report["retried"] = os.path.exists(marker)
    return report


def route_step(binary, input_path, plan, route, chunk, chunks, memory_limit, threads):
    """Routes chunk `chunk` of `chunks` of the input; the body of the Ray routing task."""
    argv = [binary, "convert", input_path, "--plan", plan, "--route", route,
            "--route-chunk", str(chunk), "--route-chunks", str(chunks), "--json", "--quiet"]
    if memory_limit:
        argv += ["--memory-limit", memory_limit]
    report = run_step(argv, _env(threads))
    report["node"] = _node_id()
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


def route_chunks(plan_json, wanted):
    """Routing chunks to use: `wanted`, or 1 where the input cannot be routed in ranges."""
    inp = plan_json["input"]
    if wanted > 1 and (inp.get("header") is None or inp["dropped"] > 0):
        return 1
    return max(1, min(wanted, inp["splats"]))


def convert(input_path, output, parts, work, binary="splat2tiles", convert_args=(),
            memory_limit=None, retries=3, cpus_per_task=1, num_cpus=None, route=None,
            part_resources=()):
    """Converts `input_path` into the tileset folder `output` in `parts` parts on Ray; the plan,
    routed files and part folders go under `work`. `route`: routing chunks (None: one per part,
    0: no routing). `part_resources`: custom resource names the tasks of part I are pinned to
    (I modulo their count). Returns the per-step reports (times, peak RSS, bytes)."""
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
    def pinned(fn, i):
        """The Ray task of `fn` for part (or chunk) `i`, pinned when resources are given."""
        o = dict(opts)
        if part_resources:
            o["resources"] = {part_resources[i % len(part_resources)]: 0.001}
        return ray.remote(fn).options(**o)

    kill = os.environ.get(KILL_ENV)
    t_route = time.time()
    route_dir = None
    route_reports = []
    chunks = route_chunks(plan_json, parts if route is None else route)
    if route != 0:
        route_dir = os.path.join(work, "route")
        route_reports = ray.get([
            pinned(route_step, c).remote(binary, input_path, plan, route_dir, c, chunks,
                                         memory_limit, threads)
            for c in range(chunks)
        ])
    samples = []
    sample_reports = []
    t1 = time.time()
    if needs_samples:
        samples = [os.path.join(work, f"samples-{i}") for i in range(parts)]
        sample_reports = ray.get([
            pinned(part_step, i).remote(binary, input_path, plan, i, "samples", samples[i], [],
                                        memory_limit, threads, work, route_dir, kill)
            for i in range(parts)
        ])
    t2 = time.time()
    part_dirs = [os.path.join(work, f"part-{i}") for i in range(parts)]
    build_reports = ray.get([
        pinned(part_step, i).remote(binary, input_path, plan, i, "build", part_dirs[i], samples,
                                    memory_limit, threads, work, route_dir, kill)
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
        "route": route_reports,
        "samples": sample_reports,
        "build": build_reports,
        "merge": merge_report,
        "seconds": {"plan": t_route - t0, "route": t1 - t_route, "samples": t2 - t1, "build": t3 - t2, "merge": t4 - t3,
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
    ap.add_argument("--route-chunks", type=int,
                    help="routing tasks (default: one per part; 0: no routing, every part "
                         "reads the whole input)")
    ap.add_argument("--part-resources",
                    help="comma-separated custom Ray resources; part I's tasks (and routing "
                         "chunk I's) run on nodes holding NAMES[I %% len(NAMES)]")
    ap.add_argument("--json", action="store_true", help="print the step reports as JSON")
    argv = list(sys.argv[1:] if argv is None else argv)
    # After `--`: convert options for the plan (e.g. -- --max-splats 16384).
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    a = ap.parse_args(argv[:argv.index("--")] if "--" in argv else argv)
    resources = [x for x in (a.part_resources or "").split(",") if x]
    r = convert(a.input, a.output, a.parts, a.work, a.binary, extra, a.memory_limit,
                a.retries, a.cpus_per_task, a.num_cpus, a.route_chunks, resources)
    if a.json:
        print(json.dumps(r))
    else:
        s = r["seconds"]
        print(f"converted {a.input} into {a.output} in {a.parts} parts: plan {s['plan']:.1f} s, "
              f"route {s['route']:.1f} s, samples {s['samples']:.1f} s, parts {s['build']:.1f} s, merge {s['merge']:.1f} s, "
              f"total {s['total']:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
