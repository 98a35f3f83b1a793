"""How READ's refinement moves plans relative to the ground truth, with no simulator in the loop.

For a trained READ run: plan for training images (where retrieval returns the image's own
demonstration, the exact answer) and test images at N = 0, 1, 10, 100; measure the final frame's
error against the ground truth (uv in pixels, depth in mm, 3D in cm after decoding to world
coordinates, the share within 3 cm) and, for the largest N, each step's drift |M̂0(k+1) - M̂0(k)|
and the end-depth error of M̂0 along the loop; and the denoiser applied once to the autoencoded
ground truth at several t (its bias: what a loop that re-anchors on its own prediction adds). A refinement that helps keeps the training
images' error near 0 as N grows and lowers the test images' error below retrieval's (N = 0).
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from readjax import failure_modes
from readjax.lab import paired
from readjax import motion as motion_lib
from readjax.diffusion.latent import codec
from readjax.diffusion.refine import refine

DEFAULT_NS = (0, 1, 10, 100)
WITHIN_M = 0.03
# per-image differences of the 3D end error smaller than this (0.1 mm) count as ties in the sign test
TIE_CM = 0.01


def end_errors(camera, plans: np.ndarray, gt: np.ndarray, image_size: int) -> dict[str, np.ndarray]:
    """Errors per episode: at the final frame uv (px), depth (mm), 3D distance (cm); at the ground
    truth's key frames the orientation error's two parts, tilt and turn (degrees,
    ``failure_modes.orientation_parts``)."""
    uv_px = np.linalg.norm(plans[:, -1, 0:2] - gt[:, -1, 0:2], axis=-1) * image_size / 2
    depth_mm = np.abs(plans[:, -1, 2] - gt[:, -1, 2]) * 1000
    pa, ra, _ = (np.asarray(x) for x in motion_lib.decode(camera, jnp.asarray(plans)))
    pb, rb, grip = (np.asarray(x) for x in motion_lib.decode(camera, jnp.asarray(gt)))
    parts = np.array([failure_modes.orientation_parts(ra[b], rb[b], frames)
                      for b, frames in enumerate(failure_modes.keyframes(grip))]).reshape(-1, 2)
    return {"uv_px": uv_px, "depth_mm": depth_mm, "err_cm": np.linalg.norm(pa[:, -1] - pb[:, -1], axis=-1) * 100,
            "tilt_deg": parts[:, 0], "turn_deg": parts[:, 1]}


def summarise(errors: dict[str, np.ndarray]) -> dict[str, float]:
    return {"uv_px_median": float(np.median(errors["uv_px"])),
            "depth_mm_median": float(np.median(errors["depth_mm"])),
            "err_cm_median": float(np.median(errors["err_cm"])),
            "within_3cm": float(np.mean(errors["err_cm"] < WITHIN_M * 100)),
            "tilt_deg_median": float(np.median(errors["tilt_deg"])),
            "turn_deg_median": float(np.median(errors["turn_deg"]))}


def refine_history(planner, images: np.ndarray, key: jax.Array, n_steps: int, batch_size: int = 50,
                   retrieval: str = "spe", gt: np.ndarray | None = None, rounds: int = 1, rank: int = 1):
    """Retrieved motions (B, 101, 10) and every step's M̂0 (rounds * N, B, 101, 10) for READ's
    planner. ``retrieval`` "spe" (the planner's) or "cheat" (the oracle's ``rank``-th neighbour of
    ``gt``: 1 is the best start the database holds, Tables 4-5; 500 a poor one, Table 8). ``rounds``
    > 1 refines again from each round's last M̂0, with the keys ``Planner.refine`` uses."""
    model = planner.model
    retrieved, hist = [], []
    for s in range(0, len(images), batch_size):
        idx = np.arange(s, s + batch_size) % len(images)  # fixed batch shape: one compile per N
        take = min(batch_size, len(images) - s)
        feats = planner.encode(images[idx])
        gt_batch = None if gt is None else np.asarray(gt)[idx]
        m_r = jnp.asarray(planner.database.motion[planner.retrieve(feats, retrieval, gt_batch, rank)])
        start, steps, batch_key = m_r, [], jax.random.fold_in(key, s)
        for r in range(rounds if n_steps > 0 else 1):
            _, h = refine(model.ae, model.ae_params, model.den, model.den_params, feats, start,
                          batch_key if r == 0 else jax.random.fold_in(batch_key, r), n_steps,
                          model.configs["sde"], return_history=True, latent=model.latent)
            steps.append(np.asarray(h)[:, :take])
            start = h[-1] if n_steps > 0 else start
        retrieved.append(np.asarray(m_r)[:take])
        hist.append(np.concatenate(steps))
    return np.concatenate(retrieved), np.concatenate(hist, axis=1)


CLEAN_TS = (1.0, 0.5, 0.1, 0.01)


def clean_input_errors(planner, images: np.ndarray, gt: np.ndarray, ts=CLEAN_TS,
                       batch_size: int = 50) -> list[dict]:
    """The denoiser applied once to the autoencoded ground truth Dec(Enc(M)) at each t: its
    end-point errors against M. A denoiser without bias keeps them at the autoencoder's own error
    (t = 0 row, ``t=None``) at small t; anything above is what the loop would add at every step."""
    model = planner.model
    enc, dec = codec(model.ae, model.ae_params, model.latent)
    roundtrip, outs = [], {t: [] for t in ts}
    for s in range(0, len(images), batch_size):
        idx = np.arange(s, s + batch_size) % len(images)
        take = min(batch_size, len(images) - s)
        feats = planner.encode(images[idx])
        m_t = dec(enc(jnp.asarray(gt[idx])))
        roundtrip.append(np.asarray(m_t)[:take])
        for t in ts:
            m0 = model.den.apply(model.den_params, feats, m_t, jnp.float32(t), method="denoise")
            outs[t].append(np.asarray(m0)[:take])
    size = planner.image_size
    rows = [{"t": None, "input": "Dec(Enc(M))", **summarise(end_errors(planner.camera, np.concatenate(roundtrip),
                                                                        gt, size))}]
    for t in ts:
        rows.append({"t": t, "input": "Dec(Enc(M))", **summarise(end_errors(planner.camera, np.concatenate(outs[t]),
                                                                          gt, size))})
    return rows


def require_read(planner) -> None:
    """refine_report diagnoses READ's refinement loop; other methods have none."""
    if planner.spec.get("method") != "read":
        raise ValueError(f"refine_report diagnoses READ's refinement; {planner.run_dir} is a "
                         f"{planner.spec.get('method')} run")


def report(planner, splits: dict[str, tuple[np.ndarray, np.ndarray]], ns=DEFAULT_NS, seed: int = 0,
           batch_size: int = 50, progress=None, retrieval: str = "spe", rounds: int | None = None,
           rank: int = 1, clean_input: bool = True) -> dict:
    """``splits``: name -> (images at the planner's size, ground-truth motions). Returns rows
    (split, N, errors: medians, and each image's 3D end error in ``err_cm``), plus per-step drift and
    end-depth error along the largest N. ``retrieval``: where refinement starts, "spe" (the
    planner's) or "cheat" (the oracle's ``rank``-th neighbour: Tables 4-5 and 8). ``rounds``:
    refinements of N steps in a row (None: the run's, ``Planner.default_rounds``). ``clean_input``:
    also the denoiser once on the autoencoded ground truth (the same for every start: one report of
    several needs it)."""
    if rank < 1 or (rank > 1 and retrieval != "cheat"):
        raise ValueError(f"rank {rank}: the oracle's neighbours are ranked from 1, and only with retrieval 'cheat'")
    rounds = planner.default_rounds if rounds is None else rounds
    require_read(planner)
    rows, loops, clean = [], {}, {}
    n_max = max(ns)
    for split, (images, gt) in splits.items():
        for n in sorted(ns):
            if progress:
                progress(f"{split} N={n}")
            if n == 0:
                plans, _ = refine_history(planner, images, jax.random.key(seed), 0, batch_size, retrieval, gt,
                                          rank=rank)
                hist = None
            else:
                _, hist = refine_history(planner, images, jax.random.key(seed), n, batch_size, retrieval, gt,
                                         rounds, rank)
                plans = hist[-1]
            errors = end_errors(planner.camera, plans, gt, planner.image_size)
            rows.append({"split": split, "N": n, **summarise(errors),
                         "err_cm": np.round(errors["err_cm"], 3).tolist()})
            if n == n_max and hist is not None:
                drift = np.abs(np.diff(hist, axis=0)).mean(axis=(1, 2, 3))  # (N - 1,)
                depth = np.abs(hist[:, :, -1, 2] - gt[None, :, -1, 2]).mean(axis=1) * 1000  # (N,)
                loops[split] = {"N": n, "drift_mean_abs": drift.tolist(), "end_depth_err_mm_mean": depth.tolist()}
        if clean_input:
            clean[split] = clean_input_errors(planner, images, gt, batch_size=batch_size)
    return {"rows": rows, "loops": loops, "clean_input": clean, "update": planner.model.configs["sde"].update,
            "retrieval": retrieval, "rank": rank, "rounds": rounds}


def check(rows: list[dict], split: str, n: int, against: int) -> dict | None:
    """Is the median 3D end error at N = ``n`` at most the one at N = ``against`` on ``split``? (The
    refinement issue's acceptance: on training images N = 100 <= N = 1, refinement does not walk
    away from a correct answer; on test images N = 100 <= N = 0, it improves on its retrieval.)
    Also per image, since both sides plan for the same images: how many end worse / better by more
    than ``TIE_CM``, the exact sign test's p and the median paired difference. None when the
    rows lack either N."""
    by = {(r["split"], r["N"]): r for r in rows}
    a, b = by.get((split, n)), by.get((split, against))
    if a is None or b is None:
        return None
    out = {"split": split, "N": n, "against": against, "median_cm": a["err_cm_median"],
           "against_median_cm": b["err_cm_median"], "holds": bool(a["err_cm_median"] <= b["err_cm_median"]),
           "margin_mm": 10 * (a["err_cm_median"] - b["err_cm_median"]),
           "worse": None, "better": None, "ties": None, "median_diff_mm": None, "sign_p": None}
    if "err_cm" in a and "err_cm" in b:  # reports before per-image errors were kept have medians only
        diff = np.asarray(a["err_cm"], float) - np.asarray(b["err_cm"], float)
        worse, better = int((diff > TIE_CM).sum()), int((diff < -TIE_CM).sum())
        out.update(worse=worse, better=better, ties=int(diff.size - worse - better),
                   median_diff_mm=10 * float(np.median(diff)), sign_p=paired.sign_test_p(worse, better))
    return out


def checks(result: dict) -> list[dict]:
    """The refinement issue's two checks on a report, where its N values allow them: training images,
    the largest N against N = 1; test images, the largest N against N = 0."""
    ns = {r["N"] for r in result["rows"]}
    if not ns:
        return []
    n_max = max(ns)
    wanted = [("train", 1), ("test", 0)]
    found = [check(result["rows"], split, n_max, against) for split, against in wanted
             if against in ns and n_max > against]
    return [c for c in found if c is not None]


def format_check(c: dict) -> str:
    verdict = "holds" if c["holds"] else f"misses by {c['margin_mm']:.2f} mm"
    line = (f"check: {c['split']} images, N = {c['N']} <= N = {c['against']} (median 3D end error "
            f"{c['median_cm']:.3f} against {c['against_median_cm']:.3f} cm): {verdict}")
    if c["worse"] is None:
        return line
    return (f"{line}; per image {c['worse']} worse / {c['better']} better / {c['ties']} within "
            f"{10 * TIE_CM:g} mm (sign test p = {c['sign_p']:.2g}), median difference {c['median_diff_mm']:+.2f} mm")


def format_checks_table(results: list[dict]) -> str:
    """One line per report (several tasks or runs): the two checks side by side."""
    lines = ["| task | run | train: N = 1 -> max, cm | holds | worse / better, p | test: N = 0 -> max, cm "
             "| holds | worse / better, p |", "|---|---|---|---|---|---|---|---|"]
    for res in results:
        cells, by_split = [], {c["split"]: c for c in checks(res)}
        for split in ("train", "test"):
            c = by_split.get(split)
            if c is None:
                cells += ["–", "–", "–"]
                continue
            cells += [f"{c['against_median_cm']:.3f} -> {c['median_cm']:.3f} (N = {c['N']})",
                      "yes" if c["holds"] else f"no (+{c['margin_mm']:.2f} mm)",
                      "–" if c["worse"] is None else f"{c['worse']} / {c['better']}, p = {c['sign_p']:.2g}"]
        run = res.get("label") or Path(str(res.get("run", "?"))).name
        lines.append(f"| {res.get('task', '?')} | {run} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def format_report(result: dict) -> str:
    """The table of the refinement issue (one line per split and N) and the loop's trajectory."""
    start = result.get("retrieval", "spe") + (f" (the oracle's neighbour {result['rank']})"
                                               if result.get("retrieval") == "cheat" else "")
    lines = [f"refinement update: {result['update']}, retrieval: {start}, "
             f"rounds: {result.get('rounds', 1)} (N = steps per round)",
             "| images | N | end uv err (px, median) | end depth err (mm, median) | 3D err (cm, median) | within 3 cm "
             "| key-frame tilt / turn err (deg, median) |",
             "|---|---|---|---|---|---|---|"]
    for r in result["rows"]:
        rot = (f"{r['tilt_deg_median']:.1f} / {r['turn_deg_median']:.1f}" if "tilt_deg_median" in r else "–")
        lines.append(f"| {r['split']} | {r['N']} | {r['uv_px_median']:.2f} | {r['depth_mm_median']:.0f} | "
                     f"{r['err_cm_median']:.1f} | {100 * r['within_3cm']:.0f} % | {rot} |")
    for split, clean in result.get("clean_input", {}).items():
        cells = "; ".join(f"{'autoencoder only' if r['t'] is None else 't = ' + format(r['t'], 'g')}: "
                          f"{r['depth_mm_median']:.1f} mm / {r['err_cm_median']:.1f} cm"
                          + (f" / {r['tilt_deg_median']:.1f}° / {r['turn_deg_median']:.1f}°" if "tilt_deg_median" in r else "")
                          for r in clean)
        lines.append(f"{split}, denoiser once on Dec(Enc(ground truth)), end depth / 3D error / key-frame tilt / "
                     f"turn error (median): {cells}")
    for split, loop in result["loops"].items():
        d = np.asarray(loop["end_depth_err_mm_mean"])
        marks = sorted({0, len(d) // 4, len(d) // 2, 3 * len(d) // 4, len(d) - 1})
        depth = " / ".join(f"{d[i]:.0f}" for i in marks)
        drift = np.asarray(loop["drift_mean_abs"])
        lines.append(f"{split}, N = {loop['N']}: mean end-depth error of M̂0 at steps "
                     f"{' / '.join(map(str, marks))}: {depth} mm; mean step drift |ΔM̂0| "
                     f"first {drift[0] if len(drift) else 0:.2e}, last {drift[-1] if len(drift) else 0:.2e}")
    lines += [format_check(c) for c in checks(result)]
    return "\n".join(lines)
