"""Write the bundled DXF floor plan ``floor.dxf``: a hall and a workshop, drawn in millimetres as
a facility planner would, with ezdxf (``pip install 'pushtrain[cad]'``).

The floor is 20 m x 12 m, (0, 0) its south-west corner, x to the east:

- layer ``WALLS``: the outer walls and a partition at x = 12 m, drawn as single lines (LINE)
  and one open polyline, with a 3 m doorway in the partition (y 4.5-7.5 m);
- layer ``RACKS``: two racks along the north of the hall and a machine in the workshop
  (closed polylines), a round column (CIRCLE) and square columns placed as block references
  (INSERT of the block ``COLUMN``, drawn on layer 0 so they take the reference's layer);
- layer ``DIMENSIONS`` (not read by ``floor_dxf.toml``): a dimension line across the doorway
  and a text label; were it read, the doorway would be shut.

Usage: python examples/maps/make_floor_dxf.py [--out DIR]   (default: this script's folder)
"""

from __future__ import annotations

import argparse
from pathlib import Path

MM = 1000.0  # drawing units per metre


def make():
    """The floor plan as an ezdxf document ($INSUNITS = 4, millimetres)."""
    import ezdxf

    doc = ezdxf.new("R2010", units=4)
    for name, color in (("WALLS", 7), ("RACKS", 3), ("DIMENSIONS", 1)):
        doc.layers.add(name, color=color)
    msp = doc.modelspace()

    def mm(points):
        return [(x * MM, y * MM) for x, y in points]

    walls = {"layer": "WALLS"}
    for a, b in (((0, 0), (20, 0)), ((20, 0), (20, 12)), ((20, 12), (0, 12))):
        msp.add_line(*mm([a, b]), dxfattribs=walls)
    msp.add_lwpolyline(mm([(0, 12), (0, 0)]), dxfattribs=walls)           # an open polyline
    msp.add_line(*mm([(12, 0), (12, 4.5)]), dxfattribs=walls)             # partition, doorway
    msp.add_line(*mm([(12, 7.5), (12, 12)]), dxfattribs=walls)            # between 4.5 and 7.5

    racks = {"layer": "RACKS"}
    for x0, y0, x1, y1 in ((1.5, 9.5, 10.5, 10.7), (1.5, 10.9, 10.5, 11.6),   # two racks
                           (15.5, 8.0, 18.5, 10.5)):                          # a machine
        msp.add_lwpolyline(mm([(x0, y0), (x1, y0), (x1, y1), (x0, y1)]), close=True,
                           dxfattribs=racks)
    msp.add_circle((7.0 * MM, 2.0 * MM), 0.25 * MM, dxfattribs=racks)   # a round column
    column = doc.blocks.new("COLUMN")
    column.add_lwpolyline(mm([(-0.2, -0.2), (0.2, -0.2), (0.2, 0.2), (-0.2, 0.2)]), close=True)
    for x, y in ((4.0, 2.0), (10.0, 2.0)):
        msp.add_blockref("COLUMN", (x * MM, y * MM), dxfattribs=racks)

    dims = {"layer": "DIMENSIONS"}
    msp.add_line(*mm([(12, 4.5), (12, 7.5)]), dxfattribs=dims)
    msp.add_text("DOOR 3000", dxfattribs={**dims, "height": 200}).set_placement((12.3 * MM, 6 * MM))
    return doc


def write(target: Path) -> None:
    """Make and save the floor plan reproducibly: the same bytes on every run (ezdxf's fixed
    dates, GUIDs and marker strings, instead of now and random ones)."""
    import ezdxf

    fixed = ezdxf.options.write_fixed_meta_data_for_testing
    ezdxf.options.write_fixed_meta_data_for_testing = True
    try:
        doc = make()
        # ezdxf lists the CLASS entries of the types in use in a set's order, which varies with
        # Python's hash seed: registered first, in name order, they keep that order
        for name in sorted(doc.entitydb.dxf_types_in_use()):
            doc.classes.add_class(name)
        doc.saveas(target)
    finally:
        ezdxf.options.write_fixed_meta_data_for_testing = fixed


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent,
                        help="folder to write floor.dxf into")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    target = args.out / "floor.dxf"
    write(target)
    print(f"wrote {target}")


if __name__ == "__main__":
    main()
