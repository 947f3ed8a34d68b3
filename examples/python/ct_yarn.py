"""A simulated CT scan of a twisted yarn of elliptical fibers, reconstructed.

1. `gencyl.phantom` makes the yarn (elliptical, twisted sections on helical paths, disjoint)
   with its exact ground truth.
2. `gencyl.ct` projects it: one cone-beam radiograph, and a parallel-beam sinogram of the
   slice halfway up the yarn (one detector row, 180 views over 180 degrees).
3. scikit-image's filtered back-projection (`iradon`) reconstructs the slice, which is compared
   with the exact labels of the same slice (`Scene.labels`, the solid's inside test).

Writes `ct-yarn.png` (radiograph | reconstruction | truth) into the current folder, or the
folder given as the first argument, and prints the Dice coefficient and fiber fractions.

    python examples/python/ct_yarn.py docs/
"""

import pathlib
import re
import sys
import tempfile

import numpy as np
from PIL import Image
from skimage.transform import iradon

import gencyl

out_dir = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else ".")

# %% The phantom: 80 fibers, major radius 0.02, aspect 0.75 +- 10 %, 20 degrees of twist.
scene_toml, truth = gencyl.phantom(
    "yarn", fibers=80, length=0.5, twist_deg=20.0, packing=0.45, radius=0.02,
    aspect=0.75, aspect_sd=0.1, section_twist=3.0, seed=2,
)
radius = truth["envelope"]["radius"]
print(f"{truth['fiber_count']} fibers, yarn radius {radius:.4f}, "
      f"fiber volume fraction {truth['fiber_volume_fraction']:.4f} (exact)")


def with_scan(ct: str) -> gencyl.Scene:
    """The phantom's scene with its [ct] table replaced by `ct`."""
    text = re.sub(r"\[ct\]\n(?:[^\[\n].*\n)*", "[ct]\n" + ct + "\n", scene_toml)
    path = pathlib.Path(tempfile.mkdtemp()) / "ct-yarn.toml"
    path.write_text(text)
    return gencyl.Scene.load(str(path))


# %% A cone-beam radiograph from the side (magnified 1.25 times on the detector), absorbance
# with mu = 1.
pixel = 3.2 * radius / 160
radiograph, _ = gencyl.ct(with_scan(
    f'beam = "cone"\ndetector = [160, 200]\npixel = [{pixel!r}, {pixel!r}]\nviews = 1\n'
    f"center = [0, 0, 0.25]\nsource_distance = 2\ndetector_distance = 0.5\n"
))

# %% The slice at z = 0.25: a parallel-beam sinogram, reconstructed by filtered back-projection.
n = 161  # odd: the centre column sits on the rotation axis, as in scikit-image's geometry
pixel = 2.2 * radius / n
scene = with_scan(
    f'beam = "parallel"\ndetector = [{n}, 1]\npixel = [{pixel!r}, {pixel!r}]\nviews = 180\n'
    f"center = [0, 0, 0.25]\nsamples = 4\n"
)
sinogram, geometry = gencyl.ct(scene)
theta = np.arange(180) * 180.0 / 180
recon = iradon(sinogram[:, 0, :].T.astype(np.float64) / pixel, theta=theta, filter_name="ramp")
# Image column X is world x, row Y is -y (see python/tests/test_ct.py), about pixel n // 2.
labels = scene.labels(origin=(-(n // 2 + 0.5) * pixel, -(n // 2 + 0.5) * pixel, 0.25 - pixel / 2),
                      voxel=pixel, size=(n, n, 1))[0]
truth_slice = np.flipud(labels > 0)

idx = np.arange(n) - n // 2
disc = idx[None, :] ** 2 + idx[:, None] ** 2 <= (n // 2) ** 2
fiber = recon > 0.5
dice = 2 * np.sum(fiber & truth_slice & disc) / (np.sum(fiber & disc) + np.sum(truth_slice & disc))
print(f"slice z = 0.25: Dice {dice:.4f}; fiber fraction of the disc {np.sum(fiber & disc) / np.sum(disc):.4f} "
      f"reconstructed, {np.sum(truth_slice & disc) / np.sum(disc):.4f} exact labels")


# %% The figure.
def grey(a, lo, hi):
    return (np.clip((a - lo) / (hi - lo), 0, 1) * 255).astype(np.uint8)


height = 200
panels = [
    grey(radiograph[0][::-1], 0, radiograph.max()),  # rows run up the detector: flip for display
    grey(recon, -0.2, 1.2),
    grey(truth_slice.astype(float), 0, 1),
]
images = [Image.fromarray(p).resize((round(p.shape[1] * height / p.shape[0]), height)) for p in panels]
canvas = Image.new("L", (sum(i.width for i in images) + 20 * (len(images) - 1), height), 255)
x = 0
for im in images:
    canvas.paste(im, (x, 0))
    x += im.width + 20
canvas.save(out_dir / "ct-yarn.png")
print(f"wrote {out_dir / 'ct-yarn.png'}")
