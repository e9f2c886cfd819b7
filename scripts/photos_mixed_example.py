#!/usr/bin/env python3
"""Make examples/buddha-mixed/photos: the 13 Buddha photos made as awkward as a web collection.

Every photo is derived from one of the 13 Buddha photos (CC BY 4.0, 1024x576 JPEG with a
35 mm focal length tag) by one change that a real internet collection has and that broke
the COLMAP scripts before (issue 28). Each changed photo still shows the same object from the
same pose, so the SfM result can be checked against the dataset's calibration:

  00006  unchanged                                   (baseline)
  00007  pixels stored rotated, EXIF orientation 6   (phone held upright: display rotates 90 CW)
  00010  pixels stored rotated, EXIF orientation 8   (display rotates 90 CCW)
  00018  pixels stored upside down, orientation 3
  00028  grey JPEG (mode L)
  00042  CMYK JPEG
  00046  downscaled to 800x450                      (another camera's size)
  00047  centre crop to 4:3, 768x576                 (another aspect ratio)
  00049  centre crop to 1:1, then upscaled to 720x720
  00052  PNG (no EXIF)
  00055  16-bit grey PNG
  00060  darker (x0.55) and warmer (R x1.15, B x0.8) (another exposure and white balance)
  00065  unchanged
  broken.jpg   the first 2 KB of a JPEG              (a failed download: must be skipped)
  noise.jpg    uniform random noise 400x300, seed 7  (a photo of something else: must not register)

Usage: photos_mixed_example.py BUDDHA_DIR OUT_DIR
Needs Pillow and numpy.
"""

import pathlib
import sys

import numpy as np
from PIL import Image

TAG_ORIENTATION = 0x0112


def save_jpeg(im, path, exif=None, orientation=None):
    kw = dict(quality=92)
    if exif is not None:
        if orientation is not None:
            exif[TAG_ORIENTATION] = orientation
        kw["exif"] = exif.tobytes()
    im.save(path, "JPEG", **kw)


def centre_crop(im, aspect):
    w, h = im.size
    cw = min(w, round(h * aspect))
    ch = min(h, round(cw / aspect))
    x0, y0 = (w - cw) // 2, (h - ch) // 2
    return im.crop((x0, y0, x0 + cw, y0 + ch))


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__.split("Usage: ")[1].split("\n")[0])
    src, out = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
    out.mkdir(parents=True, exist_ok=True)

    def load(name):
        im = Image.open(src / f"{name}.jpg")
        im.load()
        return im, im.getexif()

    for name in ["00006", "00065"]:
        im, ex = load(name)
        save_jpeg(im, out / f"{name}.jpg", ex)
    # Orientation o: the viewer applies the transform; store its inverse.
    for name, o, stored in [("00007", 6, Image.ROTATE_90), ("00010", 8, Image.ROTATE_270),
                            ("00018", 3, Image.ROTATE_180)]:
        im, ex = load(name)
        save_jpeg(im.transpose(stored), out / f"{name}.jpg", ex, orientation=o)
    im, ex = load("00028")
    save_jpeg(im.convert("L"), out / "00028.jpg", ex)
    im, ex = load("00042")
    save_jpeg(im.convert("CMYK"), out / "00042.jpg", ex)
    im, ex = load("00046")
    save_jpeg(im.resize((800, 450), Image.LANCZOS), out / "00046.jpg", ex)
    im, ex = load("00047")
    save_jpeg(centre_crop(im, 4 / 3), out / "00047.jpg", ex)
    im, ex = load("00049")
    save_jpeg(centre_crop(im, 1.0).resize((720, 720), Image.LANCZOS), out / "00049.jpg", ex)
    im, _ = load("00052")
    im.save(out / "00052.png")
    im, _ = load("00055")
    g = np.asarray(im.convert("L"), dtype=np.uint16) * 257
    Image.fromarray(g).save(out / "00055.png")
    im, ex = load("00060")
    a = np.asarray(im, dtype=np.float32) * 0.55 * np.array([1.15, 1.0, 0.8], np.float32)
    save_jpeg(Image.fromarray(np.clip(a, 0, 255).astype(np.uint8)), out / "00060.jpg", ex)
    data = (src / "00006.jpg").read_bytes()
    (out / "broken.jpg").write_bytes(data[:2048])
    rng = np.random.default_rng(7)
    noise = rng.integers(0, 256, (300, 400, 3), dtype=np.uint8)
    Image.fromarray(noise).save(out / "noise.jpg", quality=92)
    for p in sorted(out.iterdir()):
        print(p.name, p.stat().st_size)


if __name__ == "__main__":
    main()
