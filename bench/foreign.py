#!/usr/bin/env python3
"""A benchmark set whose scenes Tagsmith's synthesiser did not draw, for the full detector.

Every other set of the harness comes from `tagsmith eval generate`: the renderer, backgrounds,
lighting and noise models that stage 1 and stage 2 were trained on. A user's photographs come from
none of them. Here OpenCV draws the marker (`cv2.aruco.generateImageMarker`) on a sheet of paper
with a margin of half a cell to three cells; the sheet is posed in front of a pinhole camera and
warped into a scene of procedural clutter (value noise, shapes, lines, text, checkerboard patches)
with 0-2 distractor markers of other dictionaries (ArUco 4x4 and 5x5), uneven light, drop shadows,
blur, motion blur, noise, JPEG compression and, in some images, colour. None of these models is
Tagsmith's. The set is written in the harness's format, so every detector reads it through the
same scripts and `tagsmith eval score` / `eval compare` score it:

    bench/.venv/bin/python bench/foreign.py apriltag-36h11 /tmp/foreign36 --images 300 --seed 7
    target/release/tagsmith detect-set /tmp/foreign36 --full -o /tmp/foreign36-tagsmith.json
    bench/.venv/bin/python bench/baselines.py /tmp/foreign36 --detector apriltag -o /tmp/foreign36-apriltag.json
    target/release/tagsmith eval compare /tmp/foreign36 /tmp/foreign36-tagsmith.json /tmp/foreign36-apriltag.json

(`bench/foreign.sh OUT_DIR SEED` does all of it for both families.) AprilTag 3's tagStandard41h12
and tagCircle21h7, which OpenCV does not draw, are drawn from AprilTag's own tag images:

    bench/.venv/bin/python bench/foreign.py apriltag-standard41h12 /tmp/foreign41 --images 300 \
        --seed 7 --bitmaps apriltag-imgs/tagStandard41h12

(a checkout of github.com/AprilRobotics/apriltag-imgs); their whole drawing is the 5 cm square
and the ROI the 5 cells of 9 inside the frame.

One marker of the set's family per image: a 5 cm black square 10-100 cm from the camera, its face
turned 0-75 degrees from the line of sight, as in the harness's protocol. Each image's group is
the protocol cell nearest to that distance and angle: "normal" where it is at most 50 cm away and
turned at most 60 degrees, as there.

Pixel convention (OpenCV's, Tagsmith's): pixel centres at integer coordinates. The scene is drawn
at twice the size and averaged down (`cv2.INTER_AREA`), as a camera's pixels integrate the light
that falls on them; a point x of the large image is (x - 0.5) / 2 in the final one.
"""

import argparse
import json
import math
import os
import sys

import cv2
import numpy as np

from corners import apply, rotation

# Tagsmith family -> (OpenCV dictionary, number of IDs).
FAMILIES = {
    "apriltag-36h11": ("DICT_APRILTAG_36h11", 587),
    "aruco-6x6_250": ("DICT_6X6_250", 250),
}
# Tagsmith family -> (AprilTag's own image of ID n, number of IDs): AprilTag 3's layouts with data
# cells outside the frame, which OpenCV does not draw. The images are AprilRobotics' (the
# apriltag-imgs repository, BSD 2-clause), read from --bitmaps DIR (its folder for the family);
# none is copied here. Their ROI is AprilTag's: cells 2-7 of 9, where the frame meets the white.
BITMAP_FAMILIES = {
    "apriltag-standard41h12": ("tag41_12_{:05d}.png", 2115),
    "apriltag-circle21h7": ("tag21_07_{:05d}.png", 38),
}
DISTRACTORS = [("DICT_4X4_50", 50), ("DICT_5X5_100", 100)]
W, H = 1280, 960
FOCAL = 900.0
SIDE_M = 0.05
SS = 2  # supersampling factor of the drawing
# Large image -> final image (pixel centres at integers in both).
DOWN = np.array([[1 / SS, 0, (1 / SS - 1) / 2], [0, 1 / SS, (1 / SS - 1) / 2], [0, 0, 1]])
K = np.array([[FOCAL, 0, (W - 1) / 2], [0, FOCAL, (H - 1) / 2], [0, 0, 1]])


def value_noise(rng, octaves):
    img = np.zeros((H * SS, W * SS), np.float32)
    amplitude = 1.0
    for o in range(octaves):
        small = rng.random((3 * 2**o, 4 * 2**o)).astype(np.float32)
        img += amplitude * cv2.resize(small, (W * SS, H * SS), interpolation=cv2.INTER_CUBIC)
        amplitude *= rng.uniform(0.4, 0.7)
    img -= img.min()
    return img / max(img.max(), 1e-6)


def random_gray(rng):
    return float(rng.uniform(0, 255))


def background(rng, colour):
    """Value noise in a random range with shapes, lines and text over it, at the large size."""
    lo, hi = sorted(rng.uniform(0, 255, 2))
    channels = 3 if colour else 1
    base = np.stack([value_noise(rng, int(rng.integers(2, 7))) * (hi - lo) + lo for _ in range(channels)], -1)
    # Drawn in 8 bits (OpenCV writes text in no other depth), composed in float.
    img = np.ascontiguousarray(np.round(base if colour else base[..., 0]).astype(np.uint8))
    for _ in range(int(rng.integers(0, 40))):
        c = tuple(random_gray(rng) for _ in range(channels))
        kind = rng.integers(5)
        x, y = int(rng.integers(0, W * SS)), int(rng.integers(0, H * SS))
        size = int(rng.integers(10, 300)) * SS
        if kind == 0:
            box = ((x, y), (size, int(size * rng.uniform(0.2, 1.5))), float(rng.uniform(0, 180)))
            cv2.fillPoly(img, [cv2.boxPoints(box).astype(np.int32)], c)
        elif kind == 1:
            cv2.circle(img, (x, y), size // 2, c, -1 if rng.random() < 0.5 else int(rng.integers(1, 8)) * SS)
        elif kind == 2:
            x2, y2 = x + int(rng.normal(0, 300)) * SS, y + int(rng.normal(0, 300)) * SS
            cv2.line(img, (x, y), (x2, y2), c, int(rng.integers(1, 10)) * SS)
        elif kind == 3:
            text = "".join(chr(int(rng.integers(33, 127))) for _ in range(int(rng.integers(3, 16))))
            font = int(rng.choice([cv2.FONT_HERSHEY_SIMPLEX, cv2.FONT_HERSHEY_DUPLEX, cv2.FONT_HERSHEY_COMPLEX, cv2.FONT_HERSHEY_TRIPLEX]))
            cv2.putText(img, text, (x, y), font, rng.uniform(0.5, 4) * SS, c, int(rng.integers(1, 5)) * SS)
        else:
            # A checkerboard patch: dark squares with sharp corners, like a marker's cells.
            n, cell = int(rng.integers(2, 7)), int(rng.integers(6, 30)) * SS
            for i in range(n):
                for j in range(n):
                    if (i + j) % 2 == 0:
                        cv2.rectangle(img, (x + i * cell, y + j * cell), (x + (i + 1) * cell, y + (j + 1) * cell), c, -1)
    return img.astype(np.float32)


class OpenCvDrawing:
    """Markers OpenCV draws: the ROI is the whole black square."""

    def __init__(self, dictionary):
        self.dictionary = dictionary
        self.roi_cells = dictionary.markerSize + 2
        self.roi_side_m = SIDE_M

    def image(self, marker_id, px_per_cell):
        """The marker at `px_per_cell`, and the cells from its edge to the ROI."""
        side = self.roi_cells * px_per_cell
        return cv2.aruco.generateImageMarker(self.dictionary, marker_id, side, borderBits=1), 0


class BitmapDrawing:
    """AprilTag's own one-pixel-a-cell images, turned 180 degrees into OpenCV's convention (the
    one Tagsmith's family files follow); transparent cells are paper."""

    def __init__(self, folder, pattern):
        self.folder, self.pattern = folder, pattern
        self.roi_cells = 5
        # The drawing, not its ROI, is SIDE_M across, as an OpenCV marker's is.
        self.roi_side_m = SIDE_M * 5 / 9

    def image(self, marker_id, px_per_cell):
        path = os.path.join(self.folder, self.pattern.format(marker_id))
        rgba = cv2.imread(path, cv2.IMREAD_UNCHANGED)
        if rgba is None:
            sys.exit(f"{path}: cannot read the tag image (--bitmaps is AprilTag's folder of the family)")
        cells = np.where(rgba[..., 3] < 128, 255, rgba[..., 0]).astype(np.uint8)
        cells = np.rot90(cells, 2)
        n = cells.shape[0]
        big = cv2.resize(cells, (n * px_per_cell, n * px_per_cell), interpolation=cv2.INTER_NEAREST)
        return big, (n - self.roi_cells) // 2


def draw_sheet(rng, drawing, marker_id, px_per_cell):
    """A marker on its sheet of paper: (image, ROI side in px, sheet px from the edge to the ROI)."""
    marker, roi_offset_cells = drawing.image(marker_id, px_per_cell)
    margin = int(round(float(rng.choice([0.5, 1.0, 1.0, 1.5, 2.0, 3.0])) * px_per_cell))
    paper, ink = rng.uniform(170, 255), rng.uniform(0, 70)
    sheet = cv2.copyMakeBorder(marker, margin, margin, margin, margin, cv2.BORDER_CONSTANT, value=255)
    sheet = np.where(sheet > 127, paper, ink).astype(np.float32)
    return sheet, drawing.roi_cells * px_per_cell, margin + roi_offset_cells * px_per_cell


def random_pose(rng, distance, view_angle):
    """Marker frame (x right, y up, z towards the camera) -> camera frame: centred somewhere in
    view, `distance` metres away, its face turned `view_angle` from the line of sight."""
    at = np.array([rng.uniform(0.1, 0.9) * W, rng.uniform(0.1, 0.9) * H, 1.0])
    ray = np.linalg.solve(K, at)
    ray /= np.linalg.norm(ray)
    # Facing the camera square on, turned about the line of sight at random...
    z = -ray
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    facing = rotation(z, rng.uniform(0, 2 * math.pi)) @ np.column_stack([x, np.cross(z, x), z])
    # ...then tilted about an axis across the line of sight.
    a = rng.uniform(0, 2 * math.pi)
    axis = math.cos(a) * facing[:, 0] + math.sin(a) * facing[:, 1]
    return rotation(axis, view_angle) @ facing, distance * ray


def sheet_to_image(r, t, side_px, margin, side_m):
    """Homography sheet pixels -> final-image pixels for a ROI of `side_m` metres."""
    s = side_m / side_px
    # Sheet pixel (u, v) -> marker plane (x, y): the black square spans margin - 0.5 .. margin + side - 0.5.
    to_plane = np.array([[s, 0, -s * (margin - 0.5) - side_m / 2], [0, -s, s * (margin - 0.5) + side_m / 2], [0, 0, 1]])
    return K @ np.column_stack([r[:, 0], r[:, 1], t]) @ to_plane


def corners_of(h, side_px, margin, pad=0.0):
    a, b = margin - 0.5 - pad, margin + side_px - 0.5 + pad
    return np.array([apply(h, p) for p in [[a, a], [b, a], [b, b], [a, b]]])


def place(rng, drawing, marker_id, distance, tilt, taken):
    """A pose whose sheet lies in the image, faces the camera and misses the sheets already placed."""
    for _ in range(200):
        r, t = random_pose(rng, distance, tilt)
        # Cells drawn at least as fine as the large image shows them, so the warp only shrinks.
        across_px = FOCAL * drawing.roi_side_m / t[2] * SS
        px_per_cell = int(np.clip(math.ceil(across_px / drawing.roi_cells), 4, 96))
        sheet, side_px, margin = draw_sheet(rng, drawing, marker_id, px_per_cell)
        h = sheet_to_image(r, t, side_px, margin, drawing.roi_side_m)
        outline = corners_of(h, side_px, margin, pad=margin)
        inside = np.all(outline[:, 0] > 2) and np.all(outline[:, 0] < W - 3) and np.all(outline[:, 1] > 2) and np.all(outline[:, 1] < H - 3)
        lo, hi = outline.min(0), outline.max(0)
        apart = all(hi[0] < b[0] or lo[0] > b[2] or hi[1] < b[1] or lo[1] > b[3] for b in taken)
        if inside and apart and r[:, 2] @ (-t) > 0:
            taken.append([lo[0] - 4, lo[1] - 4, hi[0] + 4, hi[1] + 4])
            return r, t, sheet, side_px, margin, h
    return None


def paste(rng, img, sheet, h):
    big = np.linalg.inv(DOWN) @ h
    size = (W * SS, H * SS)
    # Both warps fill with 0 outside the sheet, so at its edge the sheet's warp is already
    # weighted by the coverage: composed premultiplied.
    warped = cv2.warpPerspective(sheet, big, size, flags=cv2.INTER_LINEAR)
    alpha = cv2.warpPerspective(np.ones_like(sheet), big, size, flags=cv2.INTER_LINEAR)
    if img.ndim == 3:
        # Paper is rarely neutral white: a slight tint per channel.
        tint = 1 - np.abs(rng.normal(0, 0.08, 3))
        warped, alpha = warped[..., None] * tint, alpha[..., None]
    img *= 1 - alpha
    img += warped


def light_and_lens(rng, img):
    """Uneven light, a drop shadow, blur, motion blur, noise: the final-size image, float."""
    img = cv2.resize(img, (W, H), interpolation=cv2.INTER_AREA)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    a = rng.uniform(0, 2 * math.pi)
    ramp = (xx * math.cos(a) + yy * math.sin(a)) / math.hypot(W, H)
    light = rng.uniform(0.5, 1.0) + rng.uniform(-0.4, 0.4) * ramp
    if rng.random() < 0.3:
        # A shadow's edge across the scene, softened.
        mask = np.zeros((H, W), np.float32)
        pts = np.array([[rng.uniform(0, W), rng.uniform(0, H)] for _ in range(int(rng.integers(3, 6)))], np.int32)
        cv2.fillPoly(mask, [cv2.convexHull(pts)], 1.0)
        mask = cv2.GaussianBlur(mask, (0, 0), rng.uniform(1, 15))
        light *= 1 - rng.uniform(0.3, 0.6) * mask
    img = img * (light[..., None] if img.ndim == 3 else light)
    applied = {"blur_sigma": 0.0, "noise_sigma": 0.0, "motion_blur": None, "spotlight_gain": None, "barrel_k1": None}
    if rng.random() < 0.5:
        applied["blur_sigma"] = float(rng.uniform(0.3, 1.5))
        img = cv2.GaussianBlur(img, (0, 0), applied["blur_sigma"])
    if rng.random() < 0.15:
        length = int(rng.integers(3, 10))
        angle = float(rng.uniform(0, 180))
        kernel = np.zeros((length, length), np.float32)
        c = (length - 1) / 2
        for i in range(10 * length):
            s = (i / (10 * length - 1) - 0.5) * (length - 1)
            kernel[int(round(c + s * math.sin(math.radians(angle)))), int(round(c + s * math.cos(math.radians(angle))))] = 1
        img = cv2.filter2D(img, -1, kernel / kernel.sum())
        applied["motion_blur"] = [length, angle]
    applied["noise_sigma"] = float(rng.uniform(0, 8))
    img = img + rng.normal(0, applied["noise_sigma"], img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8), applied


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("family", choices=sorted({**FAMILIES, **BITMAP_FAMILIES}))
    ap.add_argument("out_dir")
    ap.add_argument("--images", type=int, default=300)
    ap.add_argument("--seed", type=int, required=True, help="pick one nobody has tuned on")
    ap.add_argument("--bitmaps", help="AprilTag's tag images of the family (github.com/AprilRobotics/apriltag-imgs, e.g. its tagStandard41h12 folder)")
    args = ap.parse_args()

    if args.family in FAMILIES:
        name, ids = FAMILIES[args.family]
        drawing = OpenCvDrawing(cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name)))
    else:
        if not args.bitmaps:
            sys.exit(f"{args.family}: give --bitmaps, the folder of AprilTag's images of the family")
        pattern, ids = BITMAP_FAMILIES[args.family]
        drawing = BitmapDrawing(args.bitmaps, pattern)
    # Each family its own scenes for one seed.
    families = sorted(FAMILIES) + sorted(BITMAP_FAMILIES)
    rng = np.random.default_rng([args.seed, families.index(args.family)])
    os.makedirs(os.path.join(args.out_dir, "images"), exist_ok=True)
    images = []
    for n in range(args.images):
        colour = rng.random() < 0.3
        img = background(rng, colour)
        taken = []
        distance = rng.uniform(0.1, 1.0)
        tilt = math.radians(rng.uniform(0, 75))
        marker_id = int(rng.integers(0, ids))
        placed = place(rng, drawing, marker_id, distance, tilt, taken)
        if placed is None:
            sys.exit(f"image {n}: no pose puts the marker in view (distance {distance:.2f} m)")
        r, t, sheet, side_px, margin, h = placed
        for _ in range(int(rng.integers(0, 3))):
            other_name, other_ids = DISTRACTORS[int(rng.integers(len(DISTRACTORS)))]
            other = OpenCvDrawing(cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, other_name)))
            extra = place(rng, other, int(rng.integers(0, other_ids)), rng.uniform(0.1, 1.0), math.radians(rng.uniform(0, 75)), taken)
            if extra is not None:
                paste(rng, img, extra[2], extra[5])
        paste(rng, img, sheet, h)
        img, applied = light_and_lens(rng, img)
        roi = corners_of(h, side_px, margin)
        view_angle = math.degrees(math.acos(np.clip(r[:, 2] @ (-t) / np.linalg.norm(t), -1, 1)))
        assert abs(view_angle - math.degrees(tilt)) < 1e-6
        distance_cm = int(10 * round(np.linalg.norm(t) * 10))
        angle_deg = int(5 * round(view_angle / 5))
        jpeg = rng.random() < 0.7
        file = f"images/{n:06d}." + ("jpg" if jpeg else "png")
        params = [cv2.IMWRITE_JPEG_QUALITY, int(rng.integers(40, 96))] if jpeg else []
        if not cv2.imwrite(os.path.join(args.out_dir, file), img, params):
            sys.exit(f"{file}: could not write")
        marker = {
            "id": marker_id,
            "bbox": [*roi.min(0).tolist(), *roi.max(0).tolist()],
            "roi": roi.tolist(),
            "keypoints": [],
            "mask": roi.tolist(),
            "pose": {"rotation": r.tolist(), "translation_m": t.tolist(), "side_m": drawing.roi_side_m},
        }
        truth = {"family": args.family, "mode": "camera", "seed": args.seed, "width": W, "height": H, "markers": [marker], "applied": applied}
        group = {"kind": "protocol", "distance_cm": distance_cm, "angle_deg": angle_deg, "normal": distance_cm <= 50 and angle_deg <= 60}
        images.append({"file": file, "group": group, "truth": truth})
    camera = {"width": W, "height": H, "fx": FOCAL, "fy": FOCAL, "cx": (W - 1) / 2, "cy": (H - 1) / 2, "distortion": [0.0] * 5}
    manifest = {"family": args.family, "side_m": drawing.roi_side_m, "camera": camera, "seed": args.seed, "images": images}
    tmp = os.path.join(args.out_dir, "set.json.tmp")
    with open(tmp, "w") as f:
        json.dump(manifest, f)
    os.replace(tmp, os.path.join(args.out_dir, "set.json"))
    normal = sum(i["group"]["normal"] for i in images)
    print(f"{args.out_dir}: {len(images)} images of {args.family} ({normal} normal, {len(images) - normal} difficult)")


if __name__ == "__main__":
    main()
