# %% [markdown]
# # gencyl from Python: exact fiber hits and renders as numpy arrays
#
# A notebook in percent format (open it in Jupyter with jupytext, or run it as a script from
# the repository's root: `python examples/python/fibers.py`). It needs `pip install ./python`.

# %%
import time

import numpy as np

import gencyl

# %% [markdown]
# ## Elliptical, twisted fibers from arrays
# Twenty strands of five points each, elliptical (minor/major 0.5), twisted by one turn.

# %%
rng = np.random.default_rng(1)
roots = rng.uniform(-0.5, 0.5, (20, 1, 3)) * [1, 0, 1]
strands = list(roots + np.cumsum(rng.normal(0, 0.05, (20, 5, 3)) + [0, 0.25, 0], axis=1))
scene = gencyl.Scene.from_strands(strands, radius=(0.02, 0.008), ellipticity=0.5, twist=(0, 2 * np.pi))
print(scene, "bounds", scene.bounds.round(3).tolist())

# %% [markdown]
# ## Rays from the side (the near-perpendicular case) and their exact hits

# %%
lo, hi = scene.bounds
ys, zs = np.meshgrid(np.linspace(lo[1], hi[1], 300), np.linspace(lo[2], hi[2], 300))
origins = np.stack([np.full(ys.size, lo[0] - 1.0), ys.ravel(), zs.ravel()], axis=1)
directions = np.tile([1.0, 0.0, 0.0], (len(origins), 1))
start = time.perf_counter()
hits = scene.raycast(origins, directions)
took = time.perf_counter() - start
print(f"{len(origins)} rays, {len(hits['t'])} hits in {took * 1e3:.1f} ms")
print("parts hit (side, root cap, tip cap, seam):", np.bincount(hits["part"], minlength=4).tolist())
# Unit outward normals, facing the rays.
assert np.allclose(np.linalg.norm(hits["normal"], axis=1), 1.0)
assert (np.einsum("ij,ij->i", hits["normal"], directions[hits["ray"]]) <= 0).all()

# %% [markdown]
# ## Every crossing, and the X-ray path length through the fibers

# %%
all_hits = scene.raycast(origins, directions, all=True)
per_ray = np.bincount(all_hits["ray"], minlength=len(origins))
print("crossings per ray:", np.bincount(per_ray).tolist())
lengths = scene.xray(origins, directions)["length"]
print(f"longest path inside the fibers: {lengths.max():.5f}")

# %% [markdown]
# ## A render, as a float32 array (H, W, C)

# %%
image, channels = gencyl.render(scene, width=160, spp=4)
print(channels, image.shape, "mean RGB", image[..., :3].mean(axis=(0, 1)).round(4).tolist())
np.save("fibers.npy", image)
