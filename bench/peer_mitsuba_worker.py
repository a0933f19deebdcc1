"""The Mitsuba 3 side of bench/peer_mitsuba.py: runs inside the benchmark's virtual environment.

bench/peer_mitsuba.py starts it as `VENV/bin/python peer_mitsuba_worker.py THREADS` and sends one
JSON request per line on stdin; each answer is one JSON line on the original stdout (Mitsuba's
own log goes to stderr). Requests:

- load {variant, xml, spp}: load the scene and render it once, untimed for the rate (Dr.Jit
  traces and compiles the kernels in the first render; later renders reuse them).
- render {variant, xml, spp, seed, keep}: one timed render: the wall time of mi.render until its
  image is evaluated and the device is synchronised (dr.eval, dr.sync_thread), and the CPU time
  of all threads meanwhile. `keep` holds the image for `compare`.
- compare {xml, tandem: [EXR, ...], tile, save}: the kept llvm images against Tandem's renders;
  `save`, if given, is where to write the mean of Mitsuba's images (EXR).
- grad {xml, target_xml, param, lower, upper, ...}: time per gradient step of the `prb`
  integrator (`prbvolpath` for media; render,
  L1 or L2 loss, dr.backward, Adam step, clamp, params.update), after warm-up steps.
- shape_grad {variant, xml, params, axis, spp, spp_grad, seeds}: for each seed, the derivative of
  the mean image with respect to a rigid shift t of the meshes `params` (their vertex_positions)
  along `axis`, by `dr.backward` through the scene's integrator (prb_projective), and the wall
  time of that step (render, loss, backward, evaluated and synchronised); one untimed step first.
"""
import json
import os
import sys
import time

import drjit as dr
import mitsuba as mi
import numpy as np


def cpu_seconds():
    """User and system time of this process, all its threads."""
    t = os.times()
    return t.user + t.system


def timed_render(scene, spp, seed, params=None):
    t0, c0 = time.perf_counter(), cpu_seconds()
    image = mi.render(scene, params, spp=spp, seed=seed)
    dr.eval(image)
    dr.sync_thread()
    return image, time.perf_counter() - t0, cpu_seconds() - c0


class Worker:
    def __init__(self):
        self.scenes = {}  # (variant, xml) -> mi.Scene
        self.kept = {}  # xml -> [H x W x 3 arrays]

    def scene(self, variant, xml):
        mi.set_variant(variant)
        return self.scenes[(variant, xml)]

    def hello(self, _):
        llvm = [line.split()[-1] for line in open("/proc/self/maps") if "libLLVM" in line]
        return {"mitsuba": mi.__version__, "drjit": dr.__version__,
                "threads": dr.thread_count(), "libllvm": sorted(set(llvm))}

    def load(self, req):
        mi.set_variant(req["variant"])
        t0 = time.perf_counter()
        scene = mi.load_file(req["xml"])
        load_seconds = time.perf_counter() - t0
        self.scenes[(req["variant"], req["xml"])] = scene
        image, first, _ = timed_render(scene, req["spp"], 0xFFFFFF)  # seed used by no timed render
        height, width = image.shape[:2]
        return {"load_seconds": load_seconds, "first_render_seconds": first,
                "width": width, "height": height}

    def render(self, req):
        scene = self.scene(req["variant"], req["xml"])
        image, seconds, cpu = timed_render(scene, req["spp"], req["seed"])
        if req.get("keep"):
            self.kept.setdefault(req["xml"], []).append(np.array(image)[..., :3])
        return {"seconds": seconds, "cpu_seconds": cpu}

    def compare(self, req):
        mi.set_variant("scalar_rgb")  # the Bitmap reader; any variant has it
        tandem = []
        for path in req["tandem"]:
            bitmap = mi.Bitmap(path).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32,
                                             srgb_gamma=False)
            tandem.append(np.array(bitmap))
        mitsuba = np.stack(self.kept.pop(req["xml"]))
        if req.get("save"):  # Mitsuba's mean image, to look at the differences
            mi.Bitmap(mitsuba.mean(0).astype(np.float32)).write(req["save"])
        return image_difference(np.stack(tandem), mitsuba, req["tile"])

    def grad(self, req):
        mi.set_variant(req.get("variant", "llvm_ad_rgb"))
        scene = mi.load_file(req["xml"])
        params = mi.traverse(scene)
        # a texture's .data, an rgb's .value, a homogeneous medium's constant volume .value.value
        names = [req["param"] + s for s in (".data", ".value", ".value.value")]
        key = next((k for k in names if k in params), None)
        if key is None:
            raise KeyError(f"no Mitsuba parameter for {req['param']} (looked for {names})")
        target_scene = mi.load_file(req["target_xml"])
        target, _, _ = timed_render(target_scene, req["target_spp"], req["target_seed"])
        opt = mi.ad.Adam(lr=req["lr"], beta_1=req["beta1"], beta_2=req["beta2"],
                         epsilon=req["epsilon"])
        opt[key] = dr.full(type(params[key]), req["init"], params[key].shape)
        params.update(opt)
        times, losses, cpu = [], [], 0.0
        for it in range(req["warmup"] + req["iterations"]):
            if it == req["warmup"]:
                c0 = cpu_seconds()
            t0 = time.perf_counter()
            image = mi.render(scene, params, spp=req["spp"], spp_grad=req["spp_grad"],
                              seed=2 * it, seed_grad=2 * it + 1)
            diff = image - target
            loss = dr.mean(dr.abs(diff) if req["loss"] == "l1" else dr.square(diff), axis=None)
            dr.backward(loss)
            opt.step()
            opt[key] = dr.clip(opt[key], req["lower"], req["upper"])  # Tandem's range
            params.update(opt)
            dr.eval(params[key], loss)
            dr.sync_thread()
            losses.append(float(loss.array[0]))
            times.append(time.perf_counter() - t0)
        timed = times[req["warmup"]:]
        cores = (cpu_seconds() - c0) / sum(timed)
        return {"key": key, "cores": cores, "texels": list(params[key].shape),
                "first_seconds": times[0],
                "seconds": times, "mean_seconds": sum(timed) / len(timed),
                "median_seconds": sorted(timed)[len(timed) // 2], "losses": losses}


    def shape_grad(self, req):
        mi.set_variant(req.get("variant", "llvm_ad_rgb"))
        scene = mi.load_file(req["xml"], optimize=False)  # keeps meshes apart (no merging)
        params = mi.traverse(scene)
        keys = [p + ".vertex_positions" for p in req["params"]]
        base = {k: mi.Float(params[k]) for k in keys}
        direction = [0.0, 0.0, 0.0]
        direction[req["axis"]] = 1.0
        grads, times = [], []
        for i, seed in enumerate([0xFFFF] + list(req["seeds"])):  # the first: untimed, compiles
            t0 = time.perf_counter()
            t = mi.Float(0.0)
            dr.enable_grad(t)
            for k in keys:
                p = dr.unravel(mi.Point3f, base[k]) + t * mi.Vector3f(direction)
                params[k] = dr.ravel(p)
            params.update()
            image = mi.render(scene, params, spp=req["spp"], spp_grad=req["spp_grad"],
                              seed=seed, seed_grad=seed + 0x10000)
            loss = dr.mean(image[..., :3], axis=None)
            dr.backward(loss)
            g = dr.grad(t)
            dr.eval(g)
            dr.sync_thread()
            if i:
                grads.append(float(g.array[0]))
                times.append(time.perf_counter() - t0)
        return {"keys": keys, "grads": grads, "seconds": times}


def image_difference(a, b, tile):
    """Tandem (a) against Mitsuba (b), each K x H x W x 3 renders with independent seeds.

    Per channel: the relative difference of the image means, and its z-score, the difference in
    standard errors. The variance of each engine's mean image is the per-pixel sample variance
    over its seeds divided by their number; pixels are independent, so these add up. The same
    per tile x tile block, to catch a local difference that the whole-image mean dilutes.
    """
    if a.shape[1:] != b.shape[1:]:
        raise ValueError(f"image sizes differ: Tandem {a.shape[1:]}, Mitsuba {b.shape[1:]}")
    a, b = a.astype(np.float64), b.astype(np.float64)
    ma, mb = a.mean(0), b.mean(0)
    va, vb = a.var(0, ddof=1) / len(a), b.var(0, ddof=1) / len(b)  # of the mean images
    pixels = ma.shape[0] * ma.shape[1]
    diff = (ma - mb).sum((0, 1))
    se = np.sqrt((va + vb).sum((0, 1)))
    out = {"seeds": [len(a), len(b)], "mean_tandem": (ma.sum((0, 1)) / pixels).tolist(),
           "mean_mitsuba": (mb.sum((0, 1)) / pixels).tolist(),
           "rel_diff": (diff / mb.sum((0, 1))).tolist(), "z": (diff / se).tolist(),
           # per-sample variance, Tandem over Mitsuba, summed over pixels (both at the same spp)
           "variance_ratio": (va.sum((0, 1)) * len(a) / (vb.sum((0, 1)) * len(b))).tolist()}
    h, w = (ma.shape[0] // tile) * tile, (ma.shape[1] // tile) * tile

    def blocks(x):
        return x[:h, :w].reshape(h // tile, tile, w // tile, tile, 3).sum((1, 3))

    sa, sb, s2 = blocks(ma), blocks(mb), blocks(va + vb)
    # A block without noise in either image (a constant background seen directly) has no
    # standard error: it agrees (z 0) when the two differ by float rounding only, and counts
    # as beyond any bound (z +-inf) otherwise.
    d = sa - sb
    rounding = np.abs(d) <= 1e-5 * np.maximum(np.abs(sa), np.abs(sb))
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(s2 > 0, d / np.sqrt(s2), np.where(rounding, 0.0, np.sign(d) * np.inf))
    worst = np.unravel_index(np.argmax(np.abs(z)), z.shape)
    out["tile"] = {"size": tile, "count": int(z.size), "share_beyond_3": float(np.mean(abs(z) > 3)),
                   "worst_z": float(z[worst]),
                   "worst_rel_diff": float((sa[worst] - sb[worst]) / max(sb[worst], 1e-300)),
                   "worst_at": {"row": int(worst[0]) * tile, "col": int(worst[1]) * tile,
                                "channel": "rgb"[worst[2]]}}
    return out


def main():
    threads = int(sys.argv[1])
    protocol = os.fdopen(os.dup(1), "w")  # answers; everything else printed goes to stderr
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    dr.set_thread_count(threads)
    worker = Worker()
    for line in sys.stdin:
        req = json.loads(line)
        if req["cmd"] == "quit":
            break
        try:
            answer = {"ok": getattr(worker, req["cmd"])(req)}
        except Exception as e:  # reported to the driver, which stops with the message
            answer = {"error": f"{type(e).__name__}: {e}"}
        protocol.write(json.dumps(answer) + "\n")
        protocol.flush()


if __name__ == "__main__":
    main()
