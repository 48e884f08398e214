#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Renders every stand-alone scene under a folder as written, and with --compare checks each
against Mitsuba 3 at equal samples per pixel.

    bench/scene_corpus.py DIR [--compare] [--spp 64] [--threads 2] [--out out/corpus]
                          [--binary build/release/gdmlt] [--mitsuba-python PYTHON]

A scene is stand-alone when its root element is <scene>, no other file of the folder includes
it (<include filename="..."/>, looked up beside the including file and in its <path> folders,
as the loaders do; a `$parameter` in the name matches any text) and it has a sensor of its own
or through its includes: Mitsuba's `fragments/` and `include/` files are parts, not scenes.
Each scene is rendered by `gdmlt render FILE --spp N -D spp=N` (its own integrator, film and
filter; `$spp` is the only parameter Mitsuba's corpus leaves without a default) and sorted into:

  renders       exit 0 and an image;
  out of scope  exit 2 with gdmlt's "<tag type=...> is not supported: <reason>" (the plugin is
                listed);
  error         anything else (the first line of the message is listed).

With --compare, each scene that renders is also rendered by Mitsuba 3 (any interpreter that
can `import mitsuba`, by default this one; llvm_ad_rgb, the same spp and thread count) and the
table gives relMSE (bench/metrics.py) and the ratio of the image means, ours over Mitsuba's,
with a "within 2%" verdict on the mean. At equal spp both images are noisy: a scene whose light
comes through a few pixels (a point light's highlight on a smooth sphere) moves its mean by
percents from seed to seed in either renderer; --seeds K averages K renders of each.

Writes scene_corpus.json and scene_corpus.md (the table) to --out and prints the table. Exit
status 0, whatever the scenes do: a benchmark, not a test.
"""
import argparse
import glob
import json
import os
import re
import subprocess
import sys
import time
import xml.etree.ElementTree as ElementTree

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)

OUT_OF_SCOPE = re.compile(r"<(\w+)(?: type=\"?([\w.-]+)\"?)?> is not supported: ([^\n]*)")


def parse(path):
    try:
        return ElementTree.parse(path).getroot()
    except (ElementTree.ParseError, OSError):
        return None


def search_folders(path, root):
    """The folders a scene's includes are looked up in: its own, then its <path> folders."""
    base = os.path.dirname(os.path.abspath(path))
    folders = [base]
    for element in root.iter("path"):
        value = element.get("value")
        if value:
            folders.append(os.path.normpath(os.path.join(base, value)))
    return folders


def include_targets(path, root):
    """The files `path`'s includes name, found as the loaders find them; a name with a
    `$parameter` matches every file its other characters match (cbox.xml's bsdfs-$variant)."""
    targets = []
    folders = search_folders(path, root)
    for element in root.iter("include"):
        name = element.get("filename")
        if not name:
            continue
        pattern = re.sub(r"\$\w+", "*", name)
        for folder in folders:
            found = sorted(glob.glob(os.path.join(glob.escape(folder), pattern)))
            if found:
                targets += [os.path.normpath(f) for f in found if os.path.isfile(f)]
                break
    return targets


def stand_alone_scenes(directory):
    """Sorted paths of the stand-alone scenes under `directory` and the number of other XML
    files. A stand-alone scene has a <scene> root, is included by no other file, and has a
    sensor of its own or in what it includes (Mitsuba 3 renders nothing without one)."""
    files = []
    for folder, _, names in os.walk(directory):
        files += [os.path.normpath(os.path.join(folder, n)) for n in names if n.endswith(".xml")]
    roots = {f: parse(f) for f in files}
    targets = {f: include_targets(f, r) for f, r in roots.items() if r is not None}
    included = {t for ts in targets.values() for t in ts}

    def has_sensor(path, seen):
        if path in seen or roots.get(path) is None:
            return False
        seen.add(path)
        return roots[path].find(".//sensor") is not None or \
            any(has_sensor(t, seen) for t in targets.get(path, []))

    scenes = sorted(f for f, r in roots.items()
                    if r is not None and r.tag == "scene" and f not in included
                    and has_sensor(f, set()))
    return scenes, len(files) - len(scenes)


def render_ours(args, scene, out, seed):
    command = [args.binary, "render", scene, "--spp", str(args.spp), "-D", f"spp={args.spp}",
               "--seed", str(seed), "-t", str(args.threads), "-q", "-o", out]
    try:
        run = subprocess.run(command, capture_output=True, text=True, timeout=args.timeout)
    except subprocess.TimeoutExpired:
        return {"status": "error", "message": f"timed out after {args.timeout} s"}
    message = (run.stderr.strip() or run.stdout.strip()).splitlines()
    first = message[0] if message else ""
    if run.returncode == 0 and os.path.isfile(out):
        return {"status": "renders"}
    match = OUT_OF_SCOPE.search(run.stderr)
    if run.returncode == 2 and match:
        plugin = f"{match.group(1)} {match.group(2)}" if match.group(2) else match.group(1)
        return {"status": "out of scope", "plugin": plugin,
                "message": match.group(3)}
    return {"status": "error", "message": first, "exit": run.returncode}


def render_mitsuba(runner, scene, spp, out, seed):
    reply = runner.load(scene, {"spp": str(spp)}, fallback=False)
    if "error" in reply and "unused parameters" in reply["error"]:
        reply = runner.load(scene, {}, fallback=False)
    if "error" in reply:
        return reply["error"].splitlines()[0]
    runner.render_spp(spp, seed, out)
    return None


def mean_of(paths):
    import metrics
    images = [metrics.read_rgb(p) for p in paths]
    return sum(images) / len(images)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("directory")
    parser.add_argument("--binary", default=os.path.join(ROOT, "build", "release", "gdmlt"))
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--seeds", type=int, default=1, help="renders averaged per scene")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--timeout", type=float, default=900.0, help="seconds per render")
    parser.add_argument("--compare", action="store_true", help="against Mitsuba 3")
    parser.add_argument("--mitsuba-python", default=sys.executable)
    parser.add_argument("--only", default="", help="regular expression on the scene paths")
    parser.add_argument("--out", default=os.path.join(ROOT, "out", "corpus"))
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    directory = os.path.abspath(args.directory)
    scenes, parts = stand_alone_scenes(directory)
    if args.only:
        scenes = [s for s in scenes if re.search(args.only, s)]

    runner = None
    if args.compare:
        from mitsuba_runner import MitsubaRunner
        runner = MitsubaRunner(python=args.mitsuba_python, threads=args.threads,
                               log_path=os.path.join(args.out, "mitsuba.log"))
        if not runner.available:
            sys.exit(f"--compare: Mitsuba 3 is not available: {runner.error}")

    rows = []
    for index, scene in enumerate(scenes):
        name = os.path.relpath(scene, directory)
        stem = re.sub(r"[^\w.-]", "_", name[:-4])
        ours = [os.path.join(args.out, f"{stem}.gdmlt.{k}.exr") for k in range(args.seeds)]
        started = time.perf_counter()
        row = {"scene": name}
        for k, path in enumerate(ours):
            row.update(render_ours(args, scene, path, seed=k))
            if row["status"] != "renders":
                break
        row["seconds"] = round(time.perf_counter() - started, 1)
        if runner is not None and row["status"] == "renders":
            import metrics
            theirs = [os.path.join(args.out, f"{stem}.mitsuba.{k}.exr") for k in range(args.seeds)]
            problem = None
            for k, path in enumerate(theirs):
                problem = render_mitsuba(runner, scene, args.spp, path, seed=k)
                if problem:
                    break
            try:
                compare = problem is None and (mean_of(ours), mean_of(theirs))
            except (RuntimeError, ValueError) as e:
                problem = f"cannot compare the images: {e}"
            if problem:
                row["mitsuba_error"] = problem
            else:
                a, b = compare
                if a.shape != b.shape:
                    row["mitsuba_error"] = f"image sizes differ: {a.shape} and {b.shape}"
                else:
                    row["rel_mse"] = metrics.rel_mse(a, b)
                    row["mean_ratio"] = float(a.mean() / b.mean()) if b.mean() > 0 else None
        elif runner is not None and row["status"] == "error":
            # Does Mitsuba 3 load it? A scene it cannot load either (a mesh its own folders do
            # not hold: docs scenes written for the documentation script's search paths) does
            # not render as written anywhere.
            reply = runner.load(scene, {"spp": str(args.spp)}, fallback=False)
            if "error" in reply and "unused parameters" in reply["error"]:
                reply = runner.load(scene, {}, fallback=False)
            if "error" in reply:
                row["mitsuba_error"] = reply["error"].splitlines()[0]
        rows.append(row)
        print(f"[{index + 1}/{len(scenes)}] {name}: {row['status']}"
              + (f" ({row.get('plugin') or row.get('message')})" if row["status"] != "renders" else "")
              + (f" relMSE {row['rel_mse']:.3g} mean {row['mean_ratio']:.4f}"
                 if row.get("mean_ratio") else "")
              + (f" Mitsuba: {row['mitsuba_error']}" if "mitsuba_error" in row else ""),
              flush=True)
    if runner is not None:
        runner.close()

    counts = {k: sum(r["status"] == k for r in rows) for k in ("renders", "out of scope", "error")}
    compared = [r for r in rows if r.get("mean_ratio")]
    within = sum(abs(r["mean_ratio"] - 1.0) <= 0.02 for r in compared)
    both_fail = sum(r["status"] == "error" and "mitsuba_error" in r for r in rows)
    lines = [f"Scenes under {args.directory}: {len(scenes)} stand-alone ({parts} parts left out), "
             f"{counts['renders']} render, {counts['out of scope']} out of scope, "
             f"{counts['error']} errors" +
             (f" ({both_fail} of which Mitsuba 3 cannot load either); {within} of "
              f"{len(compared)} compared within 2% of Mitsuba 3's mean at {args.spp} spp"
              if runner is not None else "") + ".", "",
             "| scene | result | relMSE | mean ratio |", "|---|---|---|---|"]
    for r in rows:
        result = r["status"] if r["status"] == "renders" else \
            f"{r['status']}: {r.get('plugin') or r.get('message', '')}"
        if "mitsuba_error" in r:
            result += f" (Mitsuba: {r['mitsuba_error']})"
        rel = f"{r['rel_mse']:.3g}" if "rel_mse" in r else ""
        ratio = f"{r['mean_ratio']:.4f}" if r.get("mean_ratio") else ""
        lines.append(f"| {r['scene']} | {result} | {rel} | {ratio} |")
    table = "\n".join(lines)
    print("\n" + table)
    with open(os.path.join(args.out, "scene_corpus.md"), "w") as f:
        f.write(table + "\n")
    with open(os.path.join(args.out, "scene_corpus.json"), "w") as f:
        json.dump({"directory": args.directory, "spp": args.spp, "seeds": args.seeds,
                   "counts": counts, "compared": len(compared), "within_2_percent": within,
                   "errors_mitsuba_fails_too": both_fail,
                   "scenes": rows}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
