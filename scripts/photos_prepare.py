#!/usr/bin/env python3
"""Photos from anywhere -> upright 8-bit RGB photos that COLMAP and relight-cpc read alike.

Internet photo collections mix cameras, sizes, aspect ratios, EXIF orientations and colour
modes. For every file in SRC with an image extension this script:
1. decodes it with Pillow; a file that does not decode is listed as skipped with the reason
   (never fatal: one broken download must not stop a collection);
2. applies the EXIF orientation (tag 0x0112, values 2-8: the mirror/rotation the camera asks
   the viewer to apply; Pillow's ImageOps.exif_transpose) so the pixels are upright and the
   tag is 1 (COLMAP ignores the tag, relight-cpc must see the same pixels as COLMAP);
3. converts every colour mode to 8-bit RGB: grey (L, LA, 1), palette (P), CMYK (Adobe's
   inverted CMYK JPEGs are undone by Pillow's decoder), alpha dropped, 16-bit grey (I;16, I)
   scaled by 1/256;
4. downscales (Lanczos) so the longer side is at most --max-size (0 = keep the size);
5. writes DST/NAME: JPEG (quality 95) for JPEG sources, keeping their EXIF minus the
   orientation (COLMAP reads the focal length from it); PNG for every other source, named
   NAME.png (the original extension replaced).

It writes --manifest (default DST/../manifest.json, outside the folder COLMAP reads): per
photo the source size, mode, orientation, EXIF make, model and focal lengths, the written
name and size; and the skipped files with reasons. colmap_sparse.sh's per-model camera
grouping reads it.

Usage: photos_prepare.py SRC DST [--max-size PX] [--manifest PATH]
Needs Pillow only (Debian: python3-pil).
"""

import argparse
import json
import pathlib
import sys

from PIL import Image, ImageOps, UnidentifiedImageError

EXTS = {".jpg", ".jpeg", ".png", ".tif", ".tiff", ".webp", ".bmp"}
TAG_ORIENTATION = 0x0112
TAG_MAKE, TAG_MODEL = 0x010F, 0x0110
EXIF_IFD = 0x8769
TAG_FOCAL_35MM, TAG_FOCAL = 0xA405, 0x920A


def exif_info(im):
    """(make, model, focal 35 mm or None, focal mm or None, orientation) from the EXIF."""
    exif = im.getexif()
    sub = exif.get_ifd(EXIF_IFD) if EXIF_IFD in exif else {}
    f35 = sub.get(TAG_FOCAL_35MM)
    fmm = sub.get(TAG_FOCAL)
    return dict(make=str(exif.get(TAG_MAKE, "")).strip("\x00 "),
                model=str(exif.get(TAG_MODEL, "")).strip("\x00 "),
                focal_35mm=float(f35) if f35 else None,
                focal_mm=float(fmm) if fmm else None,
                orientation=int(exif.get(TAG_ORIENTATION, 1) or 1))


def to_rgb(im):
    """8-bit RGB from any Pillow mode."""
    if im.mode in ("I;16", "I;16B", "I;16L", "I"):
        im = im.convert("I").point(lambda v: v * (1 / 256)).convert("L")
    if im.mode == "F":
        im = im.point(lambda v: v * 255).convert("L")
    if im.mode in ("RGBA", "LA", "PA") or (im.mode == "P" and "transparency" in im.info):
        im = im.convert("RGBA")
        bg = Image.new("RGBA", im.size, (255, 255, 255, 255))
        im = Image.alpha_composite(bg, im)
    return im.convert("RGB") if im.mode != "RGB" else im


def prepare(src, dst, max_size):
    """Writes one photo; returns its manifest entry. Raises on an undecodable file."""
    with Image.open(src) as im0:
        im0.load()
        info = exif_info(im0)
        fmt = im0.format
        entry = dict(source=src.name, source_size=list(im0.size), source_mode=im0.mode,
                     source_format=fmt, **info)
        exif_bytes = im0.info.get("exif")
        im = ImageOps.exif_transpose(im0)
        if info["orientation"] != 1:
            ex = im0.getexif()
            ex[TAG_ORIENTATION] = 1
            exif_bytes = ex.tobytes()
    im = to_rgb(im)
    w, h = im.size
    s = min(1.0, max_size / max(w, h)) if max_size > 0 else 1.0
    if s < 1.0:
        im = im.resize((max(1, round(w * s)), max(1, round(h * s))), Image.LANCZOS)
    if fmt == "JPEG":
        name = src.name
        kw = dict(quality=95)
        if exif_bytes:
            kw["exif"] = exif_bytes
        im.save(dst / name, "JPEG", **kw)
    else:
        name = src.stem + ".png"
        im.save(dst / name, "PNG")
    entry.update(name=name, size=list(im.size))
    return entry


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("src")
    ap.add_argument("dst")
    ap.add_argument("--max-size", type=int, default=0)
    ap.add_argument("--manifest")
    args = ap.parse_args()
    src, dst = pathlib.Path(args.src), pathlib.Path(args.dst)
    if not src.is_dir():
        sys.exit(f"{src}: not a folder of photos")
    files = sorted(p for p in src.iterdir() if p.is_file() and p.suffix.lower() in EXTS)
    if not files:
        sys.exit(f"{src}: no photos ({', '.join(sorted(EXTS))})")
    dst.mkdir(parents=True, exist_ok=True)
    photos, skipped, names = [], [], set()
    for p in files:
        try:
            e = prepare(p, dst, args.max_size)
        except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as err:
            skipped.append(dict(source=p.name, reason=f"cannot decode: {err}"))
            print(f"{p.name}: skipped, cannot decode ({err})", flush=True)
            continue
        if e["name"] in names:
            (dst / e["name"]).unlink()
            skipped.append(dict(source=p.name, reason=f"name {e['name']} already taken"))
            print(f"{p.name}: skipped, {e['name']} already written from another file")
            continue
        names.add(e["name"])
        photos.append(e)
        rot = f", orientation {e['orientation']} applied" if e["orientation"] != 1 else ""
        print(f"{p.name}: {e['source_mode']} {e['source_size'][0]}x{e['source_size'][1]} -> "
              f"{e['name']} RGB {e['size'][0]}x{e['size'][1]}{rot}", flush=True)
    manifest = pathlib.Path(args.manifest) if args.manifest else dst.parent / "manifest.json"
    manifest.write_text(
        json.dumps(dict(photos=photos, skipped=skipped), indent=1) + "\n")
    print(f"{len(photos)} photos written, {len(skipped)} skipped")
    if not photos:
        sys.exit(f"{src}: none of the {len(files)} files decodes as a photo")


if __name__ == "__main__":
    main()
