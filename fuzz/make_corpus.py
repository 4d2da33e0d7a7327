#!/usr/bin/env python3
"""Writes the seed corpora fuzz/corpus/fuzz_<target>/ (small valid files and
edge cases for every reader, argv vectors for the option parser).

    python3 fuzz/make_corpus.py

The seeds are committed; rerun this only to change them. Regression inputs
(crashes found by fuzzing, named regress-*) are kept in the same directories
and are not touched by this script."""
import os
import struct

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus")


def put(target, name, data):
    d = os.path.join(ROOT, "fuzz_" + target)
    os.makedirs(d, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


# ---- PLY, ascii -------------------------------------------------------------
HDR = "ply\nformat ascii 1.0\n"
put("ply_ascii", "one_point.ply", HDR + "element vertex 1\nproperty float x\nproperty float y\n"
    "property float z\nend_header\n0 0 0\n")
put("ply_ascii", "normals_fields_faces.ply",
    HDR + "comment made by hand\nobj_info a note\nelement vertex 4\nproperty double x\n"
    "property double y\nproperty double z\nproperty float nx\nproperty float ny\nproperty float nz\n"
    "property uchar red\nproperty short label\nproperty uint32 id\n"
    "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
    "0 0 0 0 0 1 255 -3 0\n1 0 0 0 0 1 0 7 1\n1 1 0 0 0 1 12 0 2\n0 1 0 0 0 1 3 1 3\n"
    "3 0 1 2\n4 0 1 2 3\n")
put("ply_ascii", "shape_comment.ply",
    "ply\nformat ascii 1.0\ncomment bootsurf shape sphere\nelement vertex 2\n"
    "property float64 x\nproperty float64 y\nproperty float64 z\nend_header\n"
    "1e-300 -2.5E+3 .5\n-0 1.7976931348623157e308 4.9e-324\n")
put("ply_ascii", "empty.ply", HDR + "element vertex 0\nproperty float x\nproperty float y\n"
    "property float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n")
put("ply_ascii", "crlf_types.ply",
    (HDR + "element vertex 2\nproperty char a\nproperty float x\nproperty ushort b\n"
     "property float y\nproperty int8 c\nproperty float z\nproperty uint16 d\nend_header\n"
     "-128 1 65535 2 127 3 0\n  \t 300 4.5 -1 5 nan 6 inf  \n\n").replace("\n", "\r\n"))
put("ply_ascii", "other_elements.ply",
    HDR + "element material 2\nproperty list uchar float data\nproperty int id\n"
    "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 1\nproperty uchar flags\nproperty list uint uint vertex_index\nproperty float w\n"
    "element edge 1\nproperty int v1\nproperty int v2\nend_header\n"
    "3 0.1 0.2 0.3 7\n0 1\n0 0 0\n1 0 0\n0 1 0\n9 3 0 1 2 0.5\n0 1\n")
put("ply_ascii", "count_too_large.ply", HDR + "element vertex 1000000\nproperty float x\n"
    "property float y\nproperty float z\nend_header\n0 0 0\n1 1 1\n")
put("ply_ascii", "bad_index.ply", HDR + "element vertex 3\nproperty float x\nproperty float y\n"
    "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
    "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n")
put("ply_ascii", "no_end_header.ply", HDR + "element vertex 1\nproperty float x\n")

# ---- PLY, binary ------------------------------------------------------------
def bin_hdr(enc, body):
    return ("ply\nformat %s 1.0\n%send_header\n" % (enc, body)).encode()

XYZF = "property float x\nproperty float y\nproperty float z\n"
tri = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
put("ply_binary", "le_float_face.ply",
    bin_hdr("binary_little_endian", "element vertex 3\n" + XYZF +
            "element face 1\nproperty list uchar int vertex_indices\n")
    + b"".join(struct.pack("<3f", *p) for p in tri) + struct.pack("<B3i", 3, 0, 1, 2))
put("ply_binary", "be_double_normals.ply",
    bin_hdr("binary_big_endian", "element vertex 2\nproperty double x\nproperty double y\n"
            "property double z\nproperty float nx\nproperty float ny\nproperty float nz\n"
            "property uchar red\nproperty int16 t\n"
            "element face 1\nproperty list ushort uint vertex_indices\n")
    + struct.pack(">3d3fBh", 1.5, -2.0, 1e300, 0, 0, 1, 200, -5)
    + struct.pack(">3d3fBh", 0.0, 0.0, 0.0, 1, 0, 0, 0, 32767)
    + struct.pack(">H4I", 4, 0, 1, 1, 0))
put("ply_binary", "le_int_types.ply",
    bin_hdr("binary_little_endian", "element vertex 2\nproperty char a\nproperty int32 x\n"
            "property uint16 y\nproperty int16 z\nproperty uint b\nproperty uint8 c\n")
    + struct.pack("<biHhIB", -1, -2147483648, 65535, -32768, 4294967295, 255)
    + struct.pack("<biHhIB", 127, 2147483647, 0, 32767, 0, 0) + b"\n")
put("ply_binary", "le_list_before_vertex.ply",
    bin_hdr("binary_little_endian", "element face 2\nproperty list uchar int vertex_indices\n"
            "property float q\nelement vertex 3\n" + XYZF)
    + struct.pack("<B3if", 3, 2, 1, 0, 0.5) + struct.pack("<Bf", 0, 1.0)
    + b"".join(struct.pack("<3f", *p) for p in tri))
put("ply_binary", "le_empty.ply",
    bin_hdr("binary_little_endian", "element vertex 0\n" + XYZF))
put("ply_binary", "le_truncated.ply",
    bin_hdr("binary_little_endian", "element vertex 3\n" + XYZF)
    + struct.pack("<3f", 1, 2, 3) + b"\x00\x00")
put("ply_binary", "be_nan_inf.ply",
    bin_hdr("binary_big_endian", "element vertex 2\nproperty float x\nproperty float y\n"
            "property float z\nproperty double s\n")
    + struct.pack(">3fd", float("nan"), float("inf"), -0.0, 5e-324)
    + struct.pack(">3fd", 3.4e38, -1e-45, 1, float("-inf")))

# ---- OFF --------------------------------------------------------------------
put("off", "tetra.off", "OFF\n4 4 6\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 1 3\n"
    "3 0 2 3\n3 1 2 3\n")
put("off", "noff_comments.off", "# a comment\nNOFF # keyword\n\n3 1 0\n0 0 0 0 0 1\n"
    "1 0 0 0 0 1 # trailing\n0 1 0 0 0 1\n4 0 1 2 0 255 0 0 255\n")
put("off", "coff_rgba.off", "COFF\n3 1 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 128\n"
    "0 1 0 0 0 255 0\n3 0 1 2\n")
put("off", "coff_float_rgb.off", "COFF 2 0 0\n0 0 0 0.5 0.5 1.0\n1 1 1 0 0 0\n")
put("off", "stoff_cnoff.off", "STCNOFF\n2 0\n0 0 0 0 0 1 10 20 30 0.25 0.75\n"
    "1 1 1 1 0 0 1 2 3 1 0\n")
put("off", "no_keyword.off", "3 1 3\n0 0 0\n1 0 0\n0 1 0\n3 2 1 0\n")
put("off", "counts_too_large.off", "OFF\n99999999 1 0\n0 0 0\n1 0 0\n3 0 1 2\n")
put("off", "crlf_empty.off", "OFF\r\n0 0 0\r\n")
put("off", "polygon_degenerate.off", "OFF\n4 3 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
    "5 0 1 2 3 0\n2 0 1\n0\n")

# ---- OBJ --------------------------------------------------------------------
put("obj", "triangle.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
put("obj", "normals_full.obj", "# normals\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0 0 1\n"
    "vn 0 0 1\nvt 0 0\nf 1//1 2//2 3//3\n")
put("obj", "corner_normals.obj", "mtllib a.mtl\no thing\ng group\ns 1\nusemtl m\n"
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvn 0 0 1\nvn 0 0 -1\nvt 0.5 0.5\n"
    "f 1/1/1 2/1/2 3/1/1\nf 2/1/2 4/1/1 3/1/2\nl 1 2\np 3\n")
put("obj", "negative_quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf -4 -3 -2 -1\n"
    "f 1/1 2/2 3/3\n")
put("obj", "colours_w.obj", "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\n"
    "v 2 2 2 0.5\nf 1 2 3 4\n")
put("obj", "bad_index.obj", "v 0 0 0\nv 1 0 0\nf 1 2 3\n")
put("obj", "crlf_comments.obj", "# c\r\nv 1e3 -2.5 .5 # x\r\n\r\nv nan inf -inf\r\n"
    "v 0 0 0\r\nf 1 2 3\r\n")

# ---- XYZ --------------------------------------------------------------------
put("xyz", "three.xyz", "0 0 0\n1 0 0\n0 1 0\n")
put("xyz", "normals.xyz", "0 0 0 0 0 1\n1 0 0 0 0 1\n")
put("xyz", "scalars.txt", "# x y z a b\n// another comment\n0,0,0,1,2\n1;0;0;3;4\n"
    "0\t1\t0\t5\t6\n")
put("xyz", "pts_count.pts", "2\n1.5 2.5 3.5 10 20 30 40\n1 1 1 1 1 1 1\n")
put("xyz", "bom_crlf.xyz", b"\xef\xbb\xbf1 2 3\r\n4 5 6\r\n\r\n")
put("xyz", "mismatch.xyz", "1 2 3\n4 5\n")
put("xyz", "header_word.xyz", "x y z\n1 2 3\n")
put("xyz", "empty.xyz", "")

# ---- cli_parse ---------------------------------------------------------------
def argv(table, maxpos, *args):
    return bytes([table | (maxpos << 2)]) + b"\0".join(a.encode() for a in args)

put("cli_args", "error_ok", argv(0, 1, "-k", "30", "--degree=2", "-B50", "in.ply",
                                 "--gamma", "mean", "-o", "out.ply", "--json", "--seed", "7"))
put("cli_args", "error_help", argv(0, 1, "--help"))
put("cli_args", "error_bad_range", argv(0, 1, "-k", "1", "in.ply"))
put("cli_args", "error_flag_value", argv(0, 1, "--json=1"))
put("cli_args", "error_missing_value", argv(0, 1, "in.ply", "-k"))
put("cli_args", "render_doubles", argv(1, 1, "--azimuth", "-400", "--elevation=45.5",
                                       "--point-size", "1e-3", "--views", "4", "x.ply"))
put("cli_args", "sample_size", argv(2, 1, "-n", "1e6", "--seed", "18446744073709551616",
                                    "--sharp-angle", "nan", "mesh.off"))
put("cli_args", "compare_positional", argv(3, 7, "a.ply", "-", "--", "-b.ply", "--titles=A,B",
                                           "-x", "inf", "-i", "-2147483648", "-s", "0"))
put("cli_args", "unknown", argv(1, 0, "--unknown-option-with-a-long-name", "--=", "-"))
put("cli_args", "empty_args", argv(3, 2, "", "", "--", ""))

# ---- the CLI's read path (fuzz_cli_read): byte 0 = 0 ply, 1 off, 2 obj, 3 xyz --------
def cli_read(kind, name, data):
    put("cli_read", name, bytes([kind]) + (data if isinstance(data, bytes) else data.encode()))

def wide_header(enc, nprops, count, nl="\n"):
    lines = ["ply", "format %s 1.0" % enc, "element vertex %s" % count,
             "property float x", "property float y", "property float z"]
    lines += ["property float p%d" % i for i in range(nprops)]
    lines += ["end_header"]
    return nl.join(lines) + nl

cli_read(0, "ascii_ok", wide_header("ascii", 1, 3) + "0 0 0 1\n1 0 0 2\n0 1 0 3\n")
cli_read(0, "binary_ok", wide_header("binary_little_endian", 1, 2).encode() + struct.pack("<8f", *range(8)))
cli_read(0, "ascii_count_2p32", wide_header("ascii", 0, 4294967295) + "0 0 0\n")
cli_read(0, "ascii_count_1e15", wide_header("ascii", 0, 10**15) + "0 0 0\n")
cli_read(0, "binary_count_huge", wide_header("binary_little_endian", 0, 99999999999).encode() + bytes(12))
cli_read(0, "count_negative", wide_header("ascii", 0, -5) + "0 0 0\n")
cli_read(0, "count_overflow", wide_header("ascii", 0, "99999999999999999999999") + "0 0 0\n")
# headers far beyond libFuzzer's default 4096-byte inputs
cli_read(0, "wide_binary_3000", wide_header("binary_little_endian", 3000, 2).encode() + bytes(2 * 3003 * 4))
cli_read(0, "wide_ascii_2000", wide_header("ascii", 2000, 1) + " ".join(["1"] * 2003) + "\n")
cli_read(0, "wide_ascii_short", wide_header("ascii", 2000, 5) + " ".join(["1"] * 2003) + "\n")
dup = wide_header("ascii", 1500, 1).replace("property float p1499\n", "property float p7\n")
cli_read(0, "wide_duplicate", dup + " ".join(["1"] * 1503) + "\n")
# a binary header with lone CRs whose first data byte is 0x0A
cli_read(0, "cr_binary_0a", wide_header("binary_little_endian", 0, 1, "\r").encode()
         + b"\x0a" + bytes(11))
cli_read(1, "off_ok", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
cli_read(1, "off_absurd", "OFF\n99999999999 1 0\n0 0 0\n")
cli_read(2, "obj_ok", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
cli_read(2, "obj_cut", "v 0 0 0\nv 1 0 0\nv 0 1 0.5e")
cli_read(3, "xyz_ok", "0 0 0\n1 0 0\n0 1 0\n")
cli_read(3, "xyz_cut", "0 0 0\n1 0 0\n0 1")
