"""Inputs the fuzz harness (fuzz/, scripts/fuzz.sh) found failing, each run again through the
same target: it must now give a result or a documented ValueError / FileNotFoundError."""

import io
import pathlib
import sys
import zipfile

import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "fuzz"))
import targets  # noqa: E402

# (target, input bytes, what went wrong before the fix): found by scripts/fuzz.sh on the
# code before issue 12's io fixes (main at 663b601), 20-30 s per target.
FINDINGS = [
    # UnicodeDecodeError (Python reader opened the file as UTF-8)
    ('victoria_park', b'ODOMETR[ 0 1 1 0 0 10 0 0 10 0 31.6\nODOMETRY 1 \xff\xff1 0 0.1 10 0 0 10 0 31.6\nLANDMARK 1 7 2 1 1.6 0 1.6\nLAN RADMK2 7 1 1 1.6 0 1.6\n',
     'UnicodeDecodeError (Python reader opened the file as UTF-8)'),
    # UnicodeDecodeError building the PARAM dict
    ('carmen', b'# tiny log\nPARAM laser\xfffront_laser_resolution 1.0 nohost 0\nODOM 0 0 0 0 0 0 1.0 host 1.0\nFLiiiiASER 4 1.0 2.0 3.0 4.0 0.5 0.1 0.2 .01 0 5 1 2 3 4 5 0 0.5 0.1 0.2 0.5 0.1 0.2 0 0 0 0 0 3.0 host 3.0\nFLASER 3 1.5 2.5 81.83 0.6 0.1 0.25 0.6 0.1 0.25 4.0 host 4.0\n',
     'UnicodeDecodeError building the PARAM dict'),
    # the .gz reader died (corrupt stream, not a ValueError)
    ('carmen_gz', b'\x1f\x8b\x08\x00\x00\x00\x00\x00\x02\x03uN\xbd\n\xc20\x18\xdc\xf3\x14\x07\xce\x86\xfc}\xb6kE\x9d,\x91\xea^\x1c\xaa\x16J\x02m\x1c|{\xbfVJu\x90pp\xc9\xe5~VHmx\xa1\x8bwq*\xaa\xa2Dw\x1d\x9a\xbe\xbe\xf50\xa4\xfa\xc3\xfbf\x88\xdd3\xb51@K\x85\x10\x1fqHP\xc2\xef|\t\xf5uFu\xd2\x98\x88\xc3\xb18\xef+\xb8\xe9\xd50,\xc31\x94$\x86f\x98\x1fnf7\x13Q\xf9\xad\xbfL\t,b\xad%e\x1c\xa0\x1d\xff\xccr\x82\x1dc\xd4(\x114\x0c,\xf7\x10\xfeg/\x1b\xed\xdcb\x97\x8d\x967\x12\xd7\x12r-s\xcb\x8e\xcd\xec\xa4\xdf\x8b\x9b\xddL\xc4\x1b@gH\xeb;\x01\x00\x00',
     'the .gz reader died (corrupt stream, not a ValueError)'),
    # UnicodeDecodeError (Python reader opened the file as UTF-8)
    ('mrclam', b'# Subject # Barcode #\n1 5\n2 14\n6 9\n7 25\n8 88\n\n=====\n# Subject # x # y 0.001 0.001\n\n=====\n# Time \xfc# v # w\n100.0 0.1 0.0\n100.5 0.1 0.1\n101.0 0.4 0.0\n\n=====\n# Time # Barcode g#nR ae # Bearing\n100.2 9 2.1 0.3\n100.2 25 3.0 -0.2\n100.7 14 1.0 0.0\n100.8 77 1.0 0.0\n\n=====\n# Time # x # y # theta\n100.0 0 0 0\n101.0 0.1 0 0.05\n',
     'UnicodeDecodeError (Python reader opened the file as UTF-8)'),
]

# Hand-made inputs of the same classes, kept with the findings (each failed before its fix).
CLASSES = [
    ("carmen", b"PARAM name \xff\xfe nohost 0\nFLASER 1 1 0 0 0 0 0 0 1\n",
     "UnicodeDecodeError building the PARAM dict"),
    ("carmen_gz", b"\x1f\x8b\x08\x00\x00\x00\x00\x00\x00\x03garbage",
     "BadGzipFile / zlib.error from a corrupt .gz"),
    ("mrclam", targets.SEPARATOR.join([b"1 5\n6 inf\n", b"6 1 2 0 0\n", b"100 0.1 0\n", b"100.2 9 1 0\n"]),
     "OverflowError: int(inf) of a barcode"),
    ("victoria_park", b"ODOMETRY 0 1 1 0 0 10 0 0 10 0 31.6\n\xff\n", "UnicodeDecodeError"),
]



def _zip(members):
    """The bytes of a zip archive holding ``members`` (name -> bytes)."""
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as z:
        for name, data in members.items():
            z.writestr(name, data)
    return out.getvalue()


def _npy(header, data=b""):
    """A .npy member with a hand-written version 1.0 header."""
    text = repr(header).encode()
    pad = 64 - (10 + len(text) + 1) % 64
    return b"\x93NUMPY\x01\x00" + (len(text) + pad + 1).to_bytes(2, "little") + text + b" " * pad + b"\n" + data


# Issue 33: the learned-model loader, added to the harness (the relations reader, added too, had
# no finding).
CLASSES += [
    ("learned_model", b"", "BadZipFile from np.load"),
    ("learned_model", b"PK\x03\x04" + bytes(40), "BadZipFile from np.load"),
    ("learned_model", _zip({"weights.npy": _npy({"descr": "<f8", "fortran_order": False, "shape": (3,)}, bytes(24))}),
     "KeyError: 'meta is not a file in the archive'"),
    ("learned_model", _zip({k + ".npy": _npy({"descr": "<f8", "fortran_order": False, "shape": (1 << 40,)})
                            for k in ("weights", "mean", "scale", "meta")}),
     "numpy allocating the 8 TiB array the header claims"),
    ("learned_model", _zip({"meta.npy": _npy({"descr": "<U3", "fortran_order": False, "shape": ()}, "[1]".encode("utf-32-le")),
                            **{k + ".npy": _npy({"descr": "<f8", "fortran_order": False, "shape": (1,)}, bytes(8))
                               for k in ("weights", "mean", "scale")}}),
     "TypeError indexing a meta that is JSON but no dict"),
]


@pytest.mark.parametrize("target, data, before", FINDINGS + CLASSES,
                         ids=[f"{t}-{i}" for i, (t, _, _) in enumerate(FINDINGS + CLASSES)])
def test_fuzz_input_is_handled(tmp_path, target, data, before):
    targets.check(targets.TARGETS[target], targets.Workspace(tmp_path), data)


# Issue 48: targets for the 3-D reader into a PoseGraph3D (with its write-and-read-back check),
# TORO 3-D and TORO's EQUIV merge; their seeds, an empty file and a long EQUIV chain must give a
# documented outcome.
NEW_TARGETS = ("g2o_3d_graph", "toro_3d", "toro_equiv")
CHAIN = b"".join(b"VERTEX2 %d %d 0 0\n" % (i, i) for i in range(2000)) + \
    b"".join(b"EDGE2 %d %d 1 0 0 1 0 1 1 0 0\n" % (i, i + 1) for i in range(1999)) + \
    b"".join(b"EQUIV %d %d\n" % (i + 1, i) for i in range(1999))


@pytest.mark.parametrize("target, data", [
    (t, p.read_bytes()) for t in NEW_TARGETS
    for p in sorted((pathlib.Path(targets.__file__).parent / "seeds" / t).iterdir())
] + [(t, b"") for t in NEW_TARGETS] + [("toro_equiv", CHAIN)])
def test_new_targets_take_their_seeds(tmp_path, target, data):
    targets.check(targets.TARGETS[target], targets.Workspace(tmp_path), data)
