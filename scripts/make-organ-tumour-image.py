#!/usr/bin/env python3
"""Writes scenes/images/organ-tumour.seg.nrrd: a synthetic 3D Slicer segmentation of an
organ (an ellipsoid, label 1, "organ") holding a tumour (a ball, label 2, "tumor") 3 mm
under its top. 70 x 50 x 40 voxels of 1 mm, voxel (i, j, k) centred at (i, j, k) mm;
uint8, gzip. Deterministic: running it again writes the same voxels.

    python3 scripts/make-organ-tumour-image.py
"""
import gzip
import pathlib

DIMS = (70, 50, 40)
ORGAN_CENTRE, ORGAN_AXES = (35.0, 25.0, 18.0), (30.0, 20.0, 15.0)
TUMOUR_CENTRE, TUMOUR_RADIUS = (35.0, 25.0, 21.0), 9.0


def label(i, j, k):
    (cx, cy, cz), (a, b, c) = ORGAN_CENTRE, ORGAN_AXES
    if ((i - cx) / a) ** 2 + ((j - cy) / b) ** 2 + ((k - cz) / c) ** 2 > 1.0:
        return 0
    tx, ty, tz = TUMOUR_CENTRE
    if (i - tx) ** 2 + (j - ty) ** 2 + (k - tz) ** 2 <= TUMOUR_RADIUS**2:
        return 2
    return 1


def main():
    nx, ny, nz = DIMS
    voxels = bytes(label(i, j, k) for k in range(nz) for j in range(ny) for i in range(nx))
    header = (
        "NRRD0004\n"
        "# synthetic organ with a tumour: scripts/make-organ-tumour-image.py\n"
        "type: unsigned char\n"
        "dimension: 3\n"
        "space: left-posterior-superior\n"
        f"sizes: {nx} {ny} {nz}\n"
        "space directions: (1,0,0) (0,1,0) (0,0,1)\n"
        "kinds: domain domain domain\n"
        "encoding: gzip\n"
        "space origin: (0,0,0)\n"
        "Segment0_ID:=Segment_1\n"
        "Segment0_Name:=organ\n"
        "Segment0_LabelValue:=1\n"
        "Segment0_Layer:=0\n"
        "Segment1_ID:=Segment_2\n"
        "Segment1_Name:=tumor\n"
        "Segment1_LabelValue:=2\n"
        "Segment1_Layer:=0\n"
        "\n"
    )
    out = pathlib.Path(__file__).resolve().parent.parent / "scenes/images/organ-tumour.seg.nrrd"
    # mtime=0: the same bytes on every run.
    out.write_bytes(header.encode() + gzip.compress(voxels, mtime=0))
    print(f"{out}: {sum(v == 1 for v in voxels)} organ voxels, {sum(v == 2 for v in voxels)} tumour voxels")


if __name__ == "__main__":
    main()
