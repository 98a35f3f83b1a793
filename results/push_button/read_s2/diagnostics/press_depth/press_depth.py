"""PB: the signed depth of READ's press against the ground truth's, by outcome (BENCHMARKS 27; run.sh beside it)."""
import json, sys
import readjax, jax, numpy as np
from readjax.data import store
from readjax import motion as motion_lib
from readjax.planner import Planner

run, name = "runs/push_button/read_s2", sys.argv[1] if len(sys.argv) > 1 else "spe_N100"
rec = json.load(open(f"results/push_button/read_s2/eval/{name}.json"))
cfg = rec["eval_config"]
pl = Planner.load(run, data_root="data")
if cfg.get("refine_update"):
    pl.model.set_refine_update(cfg["refine_update"])
ds = store.load_dataset(store.split_dir("data", "push_button", "test")).subset(np.arange(100)).resized(pl.image_size)
assert ds.seeds.tolist() == rec["seeds"]
bs = cfg["batch_size"]; out = {"positions": [], "retrieved": []}
for s in range(0, 100, bs):
    idx = np.arange(s, s + bs)
    p = pl.plan(ds.rgbd[idx], jax.random.fold_in(jax.random.key(cfg["seed"]), s), N=cfg["N"] or 0,
                retrieval_method=cfg["retrieval"], gt_motion=ds.motion[idx], rank=cfg["rank"], rounds=cfg["rounds"])
    out["positions"].append(np.asarray(p.positions)); out["retrieved"].append(np.asarray(p.retrieved))
pos = np.concatenate(out["positions"])
gt_pos, _ = motion_lib.world_poses(pl.camera, ds.motion)
gt_pos = np.asarray(gt_pos)
succ = np.asarray(rec["success"], bool)
dz = (pos[:, :, 2].min(1) - gt_pos[:, :, 2].min(1)) * 1000  # mm, + = shallower press
# horizontal distance at the deepest frame of the plan
k = pos[:, :, 2].argmin(1)
lat = np.linalg.norm(pos[np.arange(100), k, :2] - gt_pos[np.arange(100), gt_pos[:, :, 2].argmin(1), :2], axis=1) * 1000
print(name, "success", succ.mean())
for lab, m in (("succeeded", succ), ("failed", ~succ)):
    if m.any():
        print(f"{lab:9s} n={m.sum():3d} press depth vs GT (mm, + shallower): median {np.median(dz[m]):+.2f} "
              f"[{np.percentile(dz[m], 10):+.2f}, {np.percentile(dz[m], 90):+.2f}]  lateral at press (mm) median {np.median(lat[m]):.1f}")
for t in (0.0, 0.2, 0.4, 0.6, 1.0):
    m = dz > t
    print(f"shallower by > {t:.1f} mm: {m.sum():3d} plans, success {succ[m].mean() if m.any() else float('nan'):.2f};"
          f"  others success {succ[~m].mean():.2f}")
json.dump({"dz_mm": dz.tolist(), "lat_mm": lat.tolist(), "success": succ.astype(int).tolist()},
          open(f"results/push_button/read_s2/diagnostics/press_depth/{name}.json", "w"))
