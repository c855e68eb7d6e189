"""Write the bundled warehouse map (``warehouse.pgm`` + ``warehouse.yaml``) in the ROS map_server
format, as a SLAM tool's ``map_saver`` would: free 254, occupied 0, unknown 205, 5 cm pixels.

The building's inside is 24 m x 16 m, x to the east, y to the north, (0, 0) its south-west inner
corner:

- two dock doors in the south wall (x 2.5-5.5 m and 14.5-17.5 m), open to a strip of apron;
- three lanes of staged pallets (6 m x 1 m each) between x = 7 and 13 m, y = 1.6 and 5 m;
- two rows of double racks (1.1 m deep) along x, with a 3.5 m cross aisle between x = 8.5 and
  12 m; a lidar sees their faces (occupied) but not inside them (unknown);
- a loading bay along the east wall: three parking bays 2.4 m wide between barriers;
- two more pallets standing about;
- sensor-like noise: the wall and rack faces are 1 to 3 pixels thick at random and a few of
  their pixels are unknown instead of occupied; a third of the free pixels along a face read
  occupied (range noise: the face is ragged by one pixel), and a few ghost returns (single
  occupied pixels) lie within 30 cm of a wall.

Usage: python examples/maps/make_warehouse.py [--out DIR]   (default: this script's folder)

The noise is seeded, so the files are the same on every run.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image

FREE, OCCUPIED, UNKNOWN = 254, 0, 205
RESOLUTION = 0.05                        # m per pixel
ORIGIN = (-0.5, -0.5)                    # lower-left corner of the image [m]
SIZE = (25.0, 17.0)                      # image extent [m]: the inside plus 0.5 m around
INSIDE = (0.0, 0.0, 24.0, 16.0)          # xmin, ymin, xmax, ymax [m]
DOORS = ((2.5, 5.5), (14.5, 17.5))       # x ranges of the dock doors in the south wall [m]
RACKS = [(x0, y0, x1, y1) for (y0, y1) in ((7.5, 8.6), (11.4, 12.5))
         for (x0, x1) in ((1.5, 8.5), (12.0, 19.0))]
BARRIERS = [(20.5, y - 0.1, 24.0, y + 0.1) for y in (0.8, 3.2, 5.6, 8.0)]   # loading bay
STAGED = [(7.0, y, 13.0, y + 1.0) for y in (1.6, 2.8, 4.0)]                 # pallet lanes
PALLETS = [(18.6, 0.3, 19.8, 1.1), (15.5, 9.6, 16.7, 10.4)]


class Raster:
    """The image (row 0 at the top) with drawing in metres."""

    def __init__(self):
        self.width = round(SIZE[0] / RESOLUTION)
        self.height = round(SIZE[1] / RESOLUTION)
        self.pixels = np.full((self.height, self.width), UNKNOWN, dtype=np.uint8)
        cols = np.arange(self.width)
        rows = np.arange(self.height)
        self.x = ORIGIN[0] + (cols + 0.5) * RESOLUTION               # pixel centres [m]
        self.y = ORIGIN[1] + (self.height - rows - 0.5) * RESOLUTION

    def mask(self, x0, y0, x1, y1) -> np.ndarray:
        """Pixels whose centre lies in the rectangle [x0, x1] x [y0, y1] [m]."""
        return ((self.y[:, None] >= y0) & (self.y[:, None] <= y1)
                & (self.x[None, :] >= x0) & (self.x[None, :] <= x1))

    def fill(self, rect, value) -> None:
        self.pixels[self.mask(*rect)] = value


def _grown(mask: np.ndarray, d: int) -> np.ndarray:
    """Pixels within ``d`` pixels (along a row or a column) of ``mask``, ``mask`` left out."""
    out = np.zeros_like(mask)
    for k in range(1, d + 1):
        out[k:, :] |= mask[:-k, :]
        out[:-k, :] |= mask[k:, :]
        out[:, k:] |= mask[:, :-k]
        out[:, :-k] |= mask[:, k:]
    return out & ~mask


def _faces(pixels: np.ndarray, solid: np.ndarray, rng) -> None:
    """Mark the pixels of ``solid`` that border free pixels as seen by a lidar: a face 1 to 3
    pixels thick (occupied), 4 % of it unknown, the rest of ``solid`` left unknown."""
    free = pixels == FREE
    depth = rng.integers(1, 4, size=free.shape)             # face thickness per pixel
    face = np.zeros_like(free)
    for d in (1, 2, 3):
        face |= solid & _grown(free, d) & (depth == d)
    pixels[face] = np.where(rng.random(face.sum()) < 0.04, UNKNOWN, OCCUPIED)


def make(seed: int = 7) -> np.ndarray:
    """The warehouse image (uint8, row 0 at the top)."""
    rng = np.random.default_rng(seed)
    r = Raster()
    r.fill(INSIDE, FREE)
    for x0, x1 in DOORS:                                     # door openings and apron
        r.fill((x0, ORIGIN[1], x1, 0.0), FREE)
    solid = r.pixels != FREE                                 # walls and the outside
    for rect in RACKS + BARRIERS + STAGED + PALLETS:
        r.fill(rect, UNKNOWN)
        solid |= r.mask(*rect)
    _faces(r.pixels, solid, rng)
    walls = r.pixels == OCCUPIED
    # range noise: a third of the free pixels next to a face read occupied (a 5 cm bump)
    bump = (r.pixels == FREE) & _grown(walls, 1) & (rng.random(walls.shape) < 0.33)
    r.pixels[bump] = OCCUPIED
    # ghost returns: single occupied pixels within 30 cm of a wall
    free = r.pixels == FREE
    ghosts = free & _grown(r.pixels == OCCUPIED, 6) & (rng.random(free.shape) < 0.002)
    r.pixels[ghosts] = OCCUPIED
    return r.pixels


YAML = """image: warehouse.pgm
resolution: {resolution}
origin: [{x}, {y}, 0.0]
negate: 0
occupied_thresh: 0.65
free_thresh: 0.196
mode: trinary
"""


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent,
                        help="folder to write warehouse.pgm and warehouse.yaml into")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    Image.fromarray(make()).save(args.out / "warehouse.pgm")
    (args.out / "warehouse.yaml").write_text(
        YAML.format(resolution=RESOLUTION, x=ORIGIN[0], y=ORIGIN[1]))
    print(f"wrote {args.out / 'warehouse.pgm'} and {args.out / 'warehouse.yaml'}")


if __name__ == "__main__":
    main()
