#!/usr/bin/env python3
"""Writes data/ct_head_vtk_quarter.nii.gz, the NIfTI-1 copy of ct_head_vtk_quarter.nrrd
(VTK's "headsq" at quarter resolution; credit and licence in data/README.md), with
nibabel: the same int16 voxels and the same geometry (voxel (i, j, k) at
(3.2 i, 3.2 j, 1.5 k) mm: the NRRD's spacings and its origin 0, as the sform and
the qform, code 1 "scanner"). volcast keeps each file's own world coordinates, so
the two files render the same bytes (tests/formats.rs).

Run from the project root with nibabel 5.4 and numpy (the NRRD is parsed here, a
raw gzip block after a text header, so no NRRD library is needed):
    python3 data/make_ct_head_nifti.py
"""

import gzip
import sys

import nibabel as nib
import numpy as np

SRC = "data/ct_head_vtk_quarter.nrrd"
DST = "data/ct_head_vtk_quarter.nii.gz"


def read_nrrd(path):
    raw = open(path, "rb").read()
    head, _, body = raw.partition(b"\n\n")
    fields = {}
    for line in head.decode("ascii").splitlines()[1:]:
        if line.startswith("#") or ":=" in line:
            continue
        key, _, value = line.partition(":")
        fields[key.strip()] = value.strip()
    assert fields["type"] == "int16" and fields["endian"] == "little", fields
    assert fields["encoding"] == "gzip", fields
    sizes = [int(x) for x in fields["sizes"].split()]
    spacings = [float(x) for x in fields["spacings"].split()]
    # x fastest on disk: read as [k][j][i], then index as [i, j, k]
    voxels = np.frombuffer(gzip.decompress(body), dtype="<i2")
    voxels = voxels.reshape(sizes[::-1]).transpose(2, 1, 0)
    return voxels, spacings


def main():
    voxels, spacings = read_nrrd(SRC)
    affine = np.diag(spacings + [1.0])
    img = nib.Nifti1Image(np.asarray(voxels, dtype=np.int16), affine)
    img.header.set_data_dtype(np.int16)
    img.header.set_xyzt_units("mm")
    img.set_sform(affine, code=1)
    img.set_qform(affine, code=1)
    img.header["descrip"] = b"VTK headsq quarter; BSD-3 Martin Schroeder Lorensen"
    nib.save(img, DST)
    back = nib.load(DST)
    assert np.array_equal(np.asarray(back.dataobj), voxels)
    print(f"{DST}: {voxels.shape} int16, spacings {spacings}", file=sys.stderr)


if __name__ == "__main__":
    main()
