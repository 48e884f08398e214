#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Mitsuba 3 path-traced renders under a time budget, run in a child process.

The bench scripts themselves need no Mitsuba: `MitsubaRunner` starts this file as a worker
under an interpreter that can `import mitsuba` (e.g. a venv's python) and talks to it with
one JSON object per line. Mitsuba's own log goes to the worker's stderr, which the parent
sends to a log file, so that stdout carries only the protocol.

    runner = MitsubaRunner(python="/tmp/mi_venv/bin/python", threads=2, log_path="mi.log")
    if runner.available:
        runner.load("scenes/cbox.xml", defines={"res": "128"})
        info = runner.render(seconds=10, seed=0, out="mitsuba.exr")
        # info: spp, seconds, chunks [[spp, s], ...], calibration_spp/_s, samples_per_s, ...
    runner.close()

Equal-time rendering
--------------------
A render starts with a short calibration render (4 spp by default) that gives Mitsuba's
cost per spp on this scene at this moment, then renders further passes whose spp is chosen
from the measured cost so far so that the total ends close to the budget. A pass fills half
of the remaining time, at least a quarter of the budget, or all of it when less remains, so
that the last passes are short and a slowdown of a shared machine during them overshoots
little; a pass is also at most MAX_LANES camera samples (Mitsuba's LLVM variants trace a
whole pass as one wavefront, so memory grows with it). The calibration pass is part of the image, and its time part of
the reported time. The image is the spp-weighted mean of the passes (exact for a box
filter, which the scenes use). `seconds` is the wall time from the first mi.render() call
until the accumulated image is evaluated: scene loading and image output are excluded, as in
gdmlt's render_s. It may exceed the budget when the calibration pass alone takes longer, or
when the machine slows down during the last pass; `overshoot` says so.

Variants and threads
--------------------
The requested variant (default llvm_ad_rgb) is tried first. The LLVM variants need an LLVM
>= 16 shared library; if DRJIT_LIBLLVM_PATH is unset the newest /usr/lib/*/libLLVM-NN.so with
NN >= 16 is used. An older LLVM can abort the worker inside the JIT, so the fallback to
scalar_rgb happens in the parent: a new worker is started when the first one fails to set
the variant or dies while loading/warming up a scene. The first render of each scene
(4 spp, JIT compilation) is a warm-up and not part of any result. Mitsuba's threads are
limited with drjit.set_thread_count(threads); the worker reports drjit.thread_count().
"""
from __future__ import annotations

import glob
import json
import math
import os
import re
import subprocess
import sys
import time

MAX_LANES = 1 << 22  # camera samples per mi.render() pass (256 x 256 x 64)
FALLBACK_VARIANT = "scalar_rgb"


# ---------------------------------------------------------------------------------------------
# Parent side
# ---------------------------------------------------------------------------------------------

def find_libllvm(min_version: int = 16) -> str | None:
    """Newest system libLLVM of at least `min_version`, or None."""
    found = []
    for path in glob.glob("/usr/lib/*/libLLVM-*.so") + glob.glob("/usr/lib/*/libLLVM.so.*") + \
            glob.glob("/usr/lib/llvm-*/lib/libLLVM*.so*"):
        m = re.search(r"libLLVM(?:-|\.so\.)(\d+)", path) or re.search(r"/llvm-(\d+)/", path)
        if m and int(m.group(1)) >= min_version:
            found.append((int(m.group(1)), path))
    return max(found)[1] if found else None


class MitsubaRunner:
    """A Mitsuba 3 worker process; `available` is False (and `error` says why) when no variant
    could be started with the given interpreter."""

    def __init__(self, python: str, threads: int, variant: str = "llvm_ad_rgb",
                 log_path: str | None = None, cwd: str | None = None):
        self.python, self.threads, self.cwd = python, threads, cwd
        self.log_path = log_path or os.devnull
        self.proc = None
        self.info: dict = {}
        self.notes: list[str] = []
        self.error: str | None = None
        self.scene: tuple | None = None
        self.libllvm = None
        self.variants = [variant] + ([FALLBACK_VARIANT] if variant != FALLBACK_VARIANT else [])
        self._start_next_variant()

    @property
    def available(self) -> bool:
        return self.proc is not None

    def _start_next_variant(self) -> bool:
        """Starts a worker with the next untried variant; False when none is left."""
        self._stop()
        while self.variants:
            variant = self.variants.pop(0)
            env = dict(os.environ)
            if variant.startswith("llvm") and "DRJIT_LIBLLVM_PATH" not in env:
                lib = find_libllvm()
                if lib is None:
                    self.notes.append(f"{variant}: no libLLVM >= 16 found (set DRJIT_LIBLLVM_PATH)")
                    continue
                env["DRJIT_LIBLLVM_PATH"] = lib
            self.libllvm = env.get("DRJIT_LIBLLVM_PATH") if variant.startswith("llvm") else None
            log = open(self.log_path, "a")
            try:
                self.proc = subprocess.Popen(
                    [self.python, os.path.abspath(__file__), "--worker", variant, str(self.threads)],
                    stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=log, text=True, env=env,
                    cwd=self.cwd)
            except OSError as e:
                self.proc, self.error = None, f"cannot start {self.python}: {e}"
                return False
            finally:
                log.close()
            hello = self._read()
            if "error" in hello:
                self.notes.append(f"{variant}: {hello['error']}")
                self._stop()
                if hello.get("fatal"):  # e.g. mitsuba not importable: another variant won't help
                    break
                continue
            self.info = hello
            return True
        self.error = "; ".join(self.notes) or "no Mitsuba variant left to try"
        return False

    def _read(self) -> dict:
        line = self.proc.stdout.readline() if self.proc else ""
        if not line:
            code = self.proc.wait() if self.proc else None
            return {"error": f"worker exited (status {code}; see {self.log_path})"}
        return json.loads(line)

    def _call(self, request: dict) -> dict:
        try:
            self.proc.stdin.write(json.dumps(request) + "\n")
            self.proc.stdin.flush()
        except (BrokenPipeError, OSError):
            return {"error": f"worker exited (see {self.log_path})"}
        return self._read()

    def load(self, scene: str, defines: dict | None = None, fallback: bool = True) -> dict:
        """Loads `scene` and renders the untimed warm-up. Falls back to the next variant when the
        worker fails here (an unusable LLVM shows up at the first JIT compilation), unless
        `fallback` is False (a corpus of scenes, some of which Mitsuba itself rejects): then the
        error is returned and the worker kept when it is still alive."""
        self.scene = (os.path.abspath(scene), dict(defines or {}))
        while self.proc is not None:
            reply = self._call({"cmd": "load", "scene": self.scene[0], "defines": self.scene[1]})
            if "error" not in reply:
                return reply
            if not fallback and self.proc.poll() is None:
                return reply
            self.notes.append(f"{self.info.get('variant')}: loading {os.path.basename(scene)} failed: "
                              f"{reply['error']}")
            if not self._start_next_variant():
                break
        return {"error": self.error}

    def render(self, seconds: float, seed: int, out: str, calibration_spp: int = 4) -> dict:
        """Renders the loaded scene for about `seconds` and writes the image to `out` (EXR)."""
        reply = self._call({"cmd": "render", "seconds": seconds, "seed": seed,
                            "out": os.path.abspath(out), "calibration_spp": calibration_spp})
        if "error" in reply:
            raise RuntimeError(f"Mitsuba render failed: {reply['error']}")
        reply["overshoot"] = reply["seconds"] > seconds * 1.05
        return reply

    def render_spp(self, spp: int, seed: int, out: str) -> dict:
        """Renders the loaded scene at `spp` samples per pixel (in passes of at most MAX_LANES
        camera samples, spp-weighted) and writes the image to `out` (EXR)."""
        reply = self._call({"cmd": "render_spp", "spp": spp, "seed": seed,
                            "out": os.path.abspath(out)})
        if "error" in reply:
            raise RuntimeError(f"Mitsuba render failed: {reply['error']}")
        return reply

    def _stop(self):
        if self.proc is not None:
            if self.proc.poll() is None:
                try:
                    self.proc.stdin.close()
                    self.proc.wait(timeout=60)
                except (OSError, subprocess.TimeoutExpired):
                    self.proc.kill()
                    self.proc.wait()
            self.proc = None

    def close(self):
        self._stop()


# ---------------------------------------------------------------------------------------------
# Worker side (runs under the Mitsuba interpreter)
# ---------------------------------------------------------------------------------------------

def _worker(variant: str, threads: int) -> int:
    # Protocol on a private copy of stdout; anything Mitsuba or drjit print goes to stderr.
    proto = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)

    def send(obj):
        proto.write(json.dumps(obj) + "\n")
        proto.flush()

    try:
        import drjit as dr
        import mitsuba as mi
    except Exception as e:  # noqa: BLE001 - reported to the parent
        send({"error": f"import mitsuba failed: {e}", "fatal": True})
        return 0
    try:
        mi.set_variant(variant)
    except Exception as e:  # noqa: BLE001
        send({"error": f"variant unavailable: {str(e).splitlines()[0] if str(e) else e!r}"})
        return 0
    has_thread_api = hasattr(dr, "set_thread_count")
    if has_thread_api:
        dr.set_thread_count(threads)
    mi.set_log_level(mi.LogLevel.Warn)
    send({"version": mi.__version__, "drjit_version": getattr(dr, "__version__", "?"),
          "variant": variant, "thread_api": has_thread_api,
          "thread_count": dr.thread_count() if hasattr(dr, "thread_count") else None})

    scene, lanes_per_spp = None, 1

    def pass_seed(seed, index):
        # Far from the seeds the references were rendered with (0 .. ~200 and 100000 on, see
        # ../shared/references/README.md): a pass sharing a reference's samples would share its
        # noise and score an error below the reference's own.
        return (0x5EED0000 + seed * 100003 + index) % (1 << 32)

    def render_pass(spp, seed):
        image = mi.render(scene, spp=spp, seed=seed)
        dr.eval(image)
        if hasattr(dr, "sync_thread"):
            dr.sync_thread()
        return image

    for line in sys.stdin:
        request = json.loads(line)
        try:
            if request["cmd"] == "load":
                t0 = time.perf_counter()
                scene = mi.load_file(request["scene"], **request["defines"])
                load_s = time.perf_counter() - t0
                w, h = (int(v) for v in scene.sensors()[0].film().crop_size())
                lanes_per_spp = w * h
                t0 = time.perf_counter()
                render_pass(4, 0xFFFF0000)  # warm-up: JIT compilation, not timed
                send({"load_s": load_s, "warmup_s": time.perf_counter() - t0, "width": w, "height": h})
            elif request["cmd"] == "render":
                budget, seed = float(request["seconds"]), int(request["seed"])
                max_chunk = max(1, MAX_LANES // lanes_per_spp)
                spp, total, chunks, accumulated = int(request["calibration_spp"]), 0, [], None
                start = time.perf_counter()
                while spp >= 1:
                    t0 = time.perf_counter()
                    image = render_pass(spp, pass_seed(seed, len(chunks)))
                    weighted = image * spp
                    accumulated = weighted if accumulated is None else accumulated + weighted
                    dr.eval(accumulated)
                    chunks.append([spp, time.perf_counter() - t0])
                    total += spp
                    elapsed = time.perf_counter() - start
                    per_spp = elapsed / total  # includes per-pass overhead: errs on the short side
                    remaining = budget - elapsed
                    # Passes of half the remaining time, but not below a quarter of the budget:
                    # a slowdown of the machine during the last pass then costs little overshoot.
                    pass_s = min(remaining, max(0.25 * budget, remaining / 2))
                    spp = min(max_chunk, math.floor(pass_s / per_spp))
                seconds = time.perf_counter() - start
                mi.Bitmap(accumulated / total).write(request["out"])
                send({"spp": total, "seconds": seconds, "chunks": chunks,
                      "calibration_spp": chunks[0][0], "calibration_s": chunks[0][1],
                      "samples_per_s": total * lanes_per_spp / seconds, "pixels": lanes_per_spp})
            elif request["cmd"] == "render_spp":
                wanted, seed = int(request["spp"]), int(request["seed"])
                max_chunk = max(1, MAX_LANES // lanes_per_spp)
                total, index, accumulated = 0, 0, None
                start = time.perf_counter()
                while total < wanted:
                    spp = min(max_chunk, wanted - total)
                    weighted = render_pass(spp, pass_seed(seed, index)) * spp
                    accumulated = weighted if accumulated is None else accumulated + weighted
                    dr.eval(accumulated)
                    total += spp
                    index += 1
                seconds = time.perf_counter() - start
                image = accumulated / total
                if image.shape[2] > 3:
                    # The beauty only: integrators with AOVs (moment, aov) put them after RGB.
                    import numpy as np
                    image = np.array(image)[:, :, :3]
                mi.Bitmap(image).write(request["out"])
                send({"spp": total, "seconds": seconds, "pixels": lanes_per_spp})
            else:
                send({"error": f"unknown command {request['cmd']!r}"})
        except Exception as e:  # noqa: BLE001 - reported to the parent, which decides
            send({"error": f"{type(e).__name__}: {e}"})
    return 0


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--worker":
        sys.exit(_worker(sys.argv[2], int(sys.argv[3])))
    sys.exit(__doc__)
