"""Does a planner read the goal from the image, and from how far? Move the goal and watch the plan.

Each test scene is rendered twice: as generated, and with its goal object (``TaskEnv.move_goal``:
RT's sphere, PB's button) moved by ``shift`` metres in a random horizontal direction. From the same
start (the oracle's ``rank``-th neighbour of the ORIGINAL ground truth, so the start does not see
the move) the planner plans on both images, and the plans' end points are compared:

    sensitivity s = (end_moved - end) . delta / |delta|^2

1 when the plan follows the goal, 0 when it ignores it. Binned by the start's distance from the
goal in the image (its final frame's uv against the ground truth's, pixels of the planner's image),
it says from how far the refinement finds the goal. The same pair of images also gives the image
features' reach: how much the denoiser's full-resolution feature map changes at each pixel, by that
pixel's distance from the goal (before or after the move). READ's denoiser sees the image only
through these features sampled along the plan's track (``Denoiser.image_tokens``; with
``input_skip`` also the input pixels under the track, which reach no further than one pixel).

Beside them, the same axis for what the denoiser was trained on (:func:`training_input_px`): how far
from their own goal its training inputs end (READ's and READ-L's, whose inputs decode the SDE's
latent marginal between a demo and one of its K retrieval neighbours): a start beyond what training
ever showed asks the denoiser for a correction it never learnt.

No simulator runs: only the renderer, the planner and the camera model.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from readjax import camera as cam_lib
from readjax import motion as motion_lib
from readjax import retrieval
from readjax.data import store
from readjax.diffusion import irsde
from readjax.diffusion import latent as latent_lib
from readjax.sim.render import SceneRenderer, render_scenes

DEFAULT_RANKS = (1, 10, 50, 200, 500)
START_BINS_PX = (0, 2, 4, 6, 8, 10, 14, 1000)
REACH_BINS_PX = (0, 2, 4, 6, 8, 10, 12, 16, 24, 1000)
FOLLOWS = 0.5  # a plan "follows" the goal when s > FOLLOWS


def horizontal_shifts(n: int, shift_m: float, seed: int = 0) -> np.ndarray:
    """(n, 3) moves of ``shift_m`` metres in uniformly random horizontal directions."""
    ang = np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi, n)
    return (np.stack([np.cos(ang), np.sin(ang), np.zeros(n)], axis=1) * shift_m).astype(np.float32)


def rgbd(rgb: np.ndarray, depth01: np.ndarray) -> np.ndarray:
    """Rendered frames as datasets store them: (B, H, W, 4) float32, RGB in [0, 1], depth normalised."""
    return np.concatenate([rgb.astype(np.float32) / 255.0, depth01[..., None]], axis=-1).astype(np.float32)


def render_pair(env, ds: store.Dataset, shifts: np.ndarray, image_size: int):
    """The dataset's scenes rendered as generated and with their goals moved by ``shifts`` (B, 3),
    both resized to ``image_size``; and the largest difference between the first rendering and the
    stored images (0 up to float rounding: the scenes are the ones the images show)."""
    moved = env.move_goal(ds.scenes, shifts)
    size = ds.image_size
    with SceneRenderer(env.mj_model, size, size, ds.meta.get("camera_name", "front")) as renderer:
        same = rgbd(*render_scenes(renderer, env, ds.scenes))
        shifted = rgbd(*render_scenes(renderer, env, moved))
    replay = float(np.abs(same - ds.rgbd).max())
    return store.resize_images(same, image_size), store.resize_images(shifted, image_size), replay


def _batches(n: int, batch_size: int):
    """(indices, kept) per batch of a fixed shape (the last one wraps around: one compile per shape)."""
    for s in range(0, n, batch_size):
        yield np.arange(s, s + batch_size) % n, min(batch_size, n - s)


def encode(planner, images: np.ndarray, batch_size: int = 50) -> jax.Array:
    """The planner's image features of every image, once (every start and both images reuse them)."""
    return jnp.concatenate([planner.encode(images[idx])[:take] for idx, take in _batches(len(images), batch_size)])


def refined_ends(planner, features: jax.Array, starts: np.ndarray, key: jax.Array, n_steps: int,
                 batch_size: int = 50) -> np.ndarray:
    """World end points (B, 3) of the planner's refinement (its default rounds) of ``starts`` (B, 101, 10)
    on ``features``: what ``Planner.plan`` plans from those starts, without its IK."""
    rounds = planner.default_rounds if n_steps > 0 else 1
    ends = []
    for idx, take in _batches(len(starts), batch_size):
        m = planner.refine(features[idx], jnp.asarray(starts[idx]), key, n_steps, rounds)
        ends.append(np.asarray(motion_lib.decode(planner.camera, m)[0])[:take, -1])
    return np.concatenate(ends)


def start_distance_px(planner, starts: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """(B,) how far each start's end lies from the ground truth's end in the image (px)."""
    return np.linalg.norm(starts[:, -1, :2] - gt[:, -1, :2], axis=-1) * planner.image_size / 2


def sensitivity(ends: np.ndarray, ends_moved: np.ndarray, shifts: np.ndarray) -> np.ndarray:
    """(B,) the plans' end displacement along the goal's move, in units of the move."""
    return np.sum((ends_moved - ends) * shifts, axis=-1) / np.sum(shifts * shifts, axis=-1)


def binned(x: np.ndarray, values: np.ndarray, bins) -> list[dict]:
    """Rows {lo, hi, n, median, mean, follows} of ``values`` by ``x`` in [lo, hi); empty bins left out."""
    rows = []
    for lo, hi in zip(bins[:-1], bins[1:]):
        m = (x >= lo) & (x < hi)
        if m.any():
            v = values[m]
            rows.append({"lo": lo, "hi": hi, "n": int(m.sum()), "median": float(np.median(v)),
                         "mean": float(np.mean(v)), "follows": float(np.mean(v > FOLLOWS))})
    return rows


def pixel_uv(size: int) -> np.ndarray:
    """(size, size, 2) normalised uv of pixel centres, (u: column, v: row) as ``sample_features`` reads."""
    c = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    u, v = np.meshgrid(c, c)
    return np.stack([u, v], axis=-1)


def feature_reach(planner, features: jax.Array, moved: jax.Array, goal_uv: np.ndarray, moved_uv: np.ndarray,
                  bins=REACH_BINS_PX) -> list[dict]:
    """How far the goal's move reaches into the denoiser's image features: per pixel, the change of
    the full-resolution feature map (from the planner's features of the images as generated and with
    the goal moved, :func:`encode`), over the map's median norm, binned by the pixel's distance (px)
    from the nearer of the goal's two positions (uv (B, 2) each)."""
    model = planner.model
    full = [np.asarray(model.den.apply(model.den_params, f, method="full_features")) for f in (features, moved)]
    change = np.linalg.norm(full[1] - full[0], axis=-1) / np.median(np.linalg.norm(full[0], axis=-1))
    grid, s = pixel_uv(full[0].shape[1]), full[0].shape[1] / 2
    dist = np.minimum(np.linalg.norm(grid[None] - goal_uv[:, None, None], axis=-1),
                      np.linalg.norm(grid[None] - moved_uv[:, None, None], axis=-1)) * s
    return binned(dist.ravel(), change.ravel(), bins)


def training_input_ends(model, motions: np.ndarray, i: np.ndarray, j: np.ndarray, t: np.ndarray,
                        key: jax.Array, chunk: int = 500) -> np.ndarray:
    """Final-frame uv (B, 2) of the denoiser's training inputs Dec(z_t) for demos ``motions[i]`` paired
    with retrieved ``motions[j]`` at times ``t`` (B,): z_t drawn from the SDE's marginal between
    Enc(M) and Enc(M_R), as READ's and READ-L's losses draw it (``sde.self_feed`` aside)."""
    sde = model.configs["sde"]
    codes = latent_lib.codes(model.ae, model.ae_params, motions, model.latent)
    _, dec = latent_lib.codec(model.ae, model.ae_params, model.latent)
    z_t = irsde.marginal_sample(key, jnp.asarray(codes[i]), jnp.asarray(codes[j]), jnp.asarray(t), sde)
    end_uv = jax.jit(lambda z: motion_lib.uv(dec(z))[:, -1])
    return np.concatenate([np.asarray(end_uv(z_t[s:s + chunk])) for s in range(0, len(i), chunk)])


def training_input_px(planner, draws: int = 4000, seed: int = 0) -> np.ndarray | None:
    """(draws,) how far from its goal (px of the planner's image) each of ``draws`` training inputs of
    the denoiser ends, drawn as training draws them: a training demo M (the held-out validation slice
    excluded), M_R uniform among its K nearest (``retrieval.training_pairs``), t ~ U(t_min, 1), the
    input Dec(z_t); the distance is its final uv against M's. None for a model without an
    autoencoder (READ-O: its SDE runs in task space)."""
    from readjax.methods.base import train_size

    model = planner.model
    if getattr(model, "ae", None) is None or "sde" not in model.configs:
        return None
    train = model.configs["train"]
    motions = np.asarray(planner.database.motion)
    n_train = train_size(len(motions), train)
    pairs = retrieval.training_pairs(planner.camera, motions, train.K, clamp=True, pool=n_train)
    rng = np.random.default_rng(seed)
    i = rng.integers(0, n_train, draws)
    j = pairs[i, rng.integers(0, pairs.shape[1], draws)]
    k_t, k_n = jax.random.split(jax.random.PRNGKey(seed))
    t = np.asarray(irsde.sample_time(k_t, (draws,), model.configs["sde"]))
    ends = training_input_ends(model, motions, i, j, t, k_n)
    return np.linalg.norm(ends - motions[i, -1, :2], axis=-1) * planner.image_size / 2


def support_summary(px: np.ndarray, bins=START_BINS_PX) -> dict:
    """Percentiles of the training inputs' distances and their share in each start bin (all bins kept)."""
    counts = np.histogram(px, bins=bins)[0]
    return {"draws": int(len(px)),
            "px_percentiles": {str(q): float(np.percentile(px, q)) for q in (50, 90, 99, 99.9)},
            "by_start": [{"lo": lo, "hi": hi, "share": float(c / len(px))}
                         for lo, hi, c in zip(bins[:-1], bins[1:], counts)]}


def report(planner, env, ds: store.Dataset, ranks=DEFAULT_RANKS, shift_m: float = 0.04, n_steps: int = 100,
           seed: int = 0, batch_size: int = 50, progress=None) -> dict:
    """The goal-shift diagnostic on ``ds`` (a test split with its scenes) for a READ-family planner."""
    if ds.scenes is None:
        raise ValueError("the dataset stores no scenes to move the goal in (regenerate it: format >= 2)")
    if shift_m <= 0:
        raise ValueError(f"the goal's move must be > 0 m, got {shift_m}")
    say = progress or (lambda msg: None)
    shifts = horizontal_shifts(len(ds), shift_m, seed)
    images, moved, replay = render_pair(env, ds, shifts, planner.image_size)
    goal = np.asarray(env.goal(ds.scenes))
    uv0 = np.asarray(cam_lib.project_uvz(planner.camera, jnp.asarray(goal)))[:, :2]
    uv1 = np.asarray(cam_lib.project_uvz(planner.camera, jnp.asarray(goal + shifts)))[:, :2]
    gt, key = np.asarray(ds.motion), jax.random.PRNGKey(seed)
    features = [encode(planner, x, batch_size) for x in (images, moved)]
    per_rank = []
    for rank in ranks:
        say(f"rank {rank}: planning on both images (N = {n_steps})")
        # the same start for both images: the oracle's neighbour of the original ground truth
        starts = np.asarray(planner.database.motion)[planner.retrieve(None, "cheat", gt, rank)]
        ends, ends_moved = (refined_ends(planner, f, starts, key, n_steps, batch_size) for f in features)
        s = sensitivity(ends, ends_moved, shifts)
        per_rank.append({"rank": rank, "start_px": start_distance_px(planner, starts, gt).tolist(),
                         "sensitivity": s.tolist(),
                         "end_moved_cm": (np.linalg.norm(ends_moved - ends, axis=-1) * 100).tolist()})
    start = np.concatenate([r["start_px"] for r in per_rank])
    sens = np.concatenate([r["sensitivity"] for r in per_rank])
    support = training_input_px(planner, seed=seed)
    return {"task": ds.task, "images": len(ds), "shift_m": shift_m, "N": n_steps, "seed": seed,
            "rounds": planner.default_rounds, "image_size": planner.image_size,
            "goal_move_px_median": float(np.median(np.linalg.norm(uv1 - uv0, axis=-1)) * planner.image_size / 2),
            "replay_max_abs_diff": replay, "ranks": per_rank,
            "by_start": binned(start, sens, START_BINS_PX),
            "feature_reach": feature_reach(planner, *features, uv0, uv1),
            "training_inputs": None if support is None else support_summary(support)}


def _bin_label(row: dict) -> str:
    return f"{row['lo']}-{row['hi']} px" if row["hi"] < 1000 else f">= {row['lo']} px"


def _share(key, share: dict) -> str:
    return "–" if key not in share else f"{share[key]:.1%}"


def format_lines(result: dict) -> list[str]:
    lines = [f"{result['task']}: goal moved {result['shift_m'] * 100:.1f} cm (median {result['goal_move_px_median']:.1f} px)"
             f" on {result['images']} test scenes; N = {result['N']}, {result['rounds']} round(s); "
             f"re-rendered scenes vs stored images: max |diff| {result['replay_max_abs_diff']:.1e}",
             "", "| start (oracle's i-th) | start, median px | sensitivity, median | follows (s > 0.5) |",
             "|---|---|---|---|"]
    for r in result["ranks"]:
        s = np.asarray(r["sensitivity"])
        lines.append(f"| i = {r['rank']} | {np.median(r['start_px']):.1f} | {np.median(s):+.2f} | "
                     f"{np.mean(s > FOLLOWS):.0%} |")
    support = result.get("training_inputs")
    share = {} if support is None else {(b["lo"], b["hi"]): b["share"] for b in support["by_start"]}
    lines += ["", "| start's distance from the goal | plans | sensitivity, median | follows "
                  "| training inputs here |", "|---|---|---|---|---|"]
    lines += [f"| {_bin_label(b)} | {b['n']} | {b['median']:+.2f} | {b['follows']:.0%} | "
              f"{_share((b['lo'], b['hi']), share)} |" for b in result["by_start"]]
    if support is not None:
        q = support["px_percentiles"]
        lines += ["", f"The denoiser's training inputs ({support['draws']} drawn as training draws them) end "
                      f"{q['50']:.1f} / {q['90']:.1f} / {q['99']:.1f} / {q['99.9']:.1f} px from their goal "
                      "(percentiles 50 / 90 / 99 / 99.9)."]
    lines += ["", "| pixel's distance from the goal | feature change / median feature norm, median |", "|---|---|"]
    lines += [f"| {_bin_label(b)} | {b['median']:.3f} |" for b in result["feature_reach"]]
    return lines


def plot(result: dict, path) -> None:
    """Sensitivity against the start's distance (every plan, and the bins' medians) beside the
    features' change against the pixel's distance from the goal."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    for r in result["ranks"]:
        a.scatter(r["start_px"], r["sensitivity"], s=8, alpha=0.5, label=f"i = {r['rank']}")
    mid = [min(row["hi"], row["lo"] + 6) / 2 + row["lo"] / 2 for row in result["by_start"]]
    a.plot(mid, [row["median"] for row in result["by_start"]], "k-o", label="median by bin")
    a.axhline(1.0, color="grey", lw=0.8, ls="--")
    a.axhline(0.0, color="grey", lw=0.8)
    a.set(xlabel="start's end, distance from the goal (px)", ylabel="sensitivity of the plan's end",
          title=f"{result['task']}: does the plan follow a moved goal?", ylim=(-1.5, 2.0))
    a.legend(fontsize=7, loc="upper right")
    support = result.get("training_inputs")
    if support is not None:  # where the denoiser's training inputs end, on the same axis
        twin = a.twinx()
        rows = [r for r in support["by_start"] if r["hi"] < 1000]
        twin.bar([r["lo"] for r in rows], [r["share"] for r in rows], width=[r["hi"] - r["lo"] for r in rows],
                 align="edge", color="tab:grey", alpha=0.25)
        twin.set_ylabel("share of the denoiser's training inputs", color="tab:grey")
        twin.set_ylim(0, 1)
    reach = result["feature_reach"]
    b.plot([min(row["hi"], row["lo"] + 8) / 2 + row["lo"] / 2 for row in reach], [row["median"] for row in reach], "o-")
    b.set(xlabel="pixel's distance from the goal (px)", ylabel="feature change / median norm",
          title="how far the move reaches into the features")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
