#!/usr/bin/env python3
"""Writes the fuzz targets' seed corpora (tests/fuzz/corpus/<target>/) and the job JSON dictionary.

The seeds are committed; run this again only to change them:

    python3 tests/fuzz/make_seeds.py [--invr build/bin/invr]

Pure Python (zlib, struct) except for two tools: protoc encodes the TaskResult seeds from the text
protos below, and `invr example NAME` (when --invr names a built binary) prints the zoo's jobs.
Every file is small (a few KB at most): libFuzzer's default -max_len is the largest seed.
"""

import argparse
import pathlib
import re
import shutil
import struct
import subprocess
import zlib

ROOT = pathlib.Path(__file__).resolve().parents[2]
CORPUS = ROOT / "tests/fuzz/corpus"


def write(target, name, data):
    d = CORPUS / target
    d.mkdir(parents=True, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    (d / name).write_bytes(data)


# --------------------------------------------------------------------------------------- OBJ

OBJ_FULL = """# quad and triangle with positions, uvs and normals; a polygon, relative indices, groups
mtllib missing.mtl
o thing
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0.5 0.5 1
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
vn 0 0 -1
g top
usemtl red
s 1
f 1/1/1 2/2/1 3/3/1 4/4/1
g side
s off
f -5/-4/-1 -4/-3/-1 -1/-2/-1
l 1 2
"""

OBJ_TETRA_VN = """# closed tetrahedron, v//vn faces
v 0 0 0
v 1 0 0
v 0 1 0
v 0 0 1
vn -0.577 -0.577 -0.577
vn 0.577 0.577 0.577
f 1//1 3//1 2//1
f 1//1 2//1 4//1
f 1//1 4//1 3//1
f 2//2 3//2 4//2
"""

OBJ_VT_ONLY = """v -1 -1 0
v 1 -1 0
v 1 1 0
vt 0 0
vt 1 0
vt 1 1
f 1/1 2/2 3/3
"""

# Malicious: normal indices out of range, index 0, huge index, non-finite coordinates.
OBJ_BAD_NORMALS = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//5 2//5 3//5\n"
OBJ_BAD_INDICES = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99\nf 0 1 2\nf 1 2 4294967295\nf -7 1 2\n"
OBJ_NAN = "v nan 0 0\nv 1 inf 0\nv 0 1 -1e39\nvt nan nan\nf 1/1 2/1 3/1\n"
OBJ_NONMANIFOLD = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 2 5\nf 1 1 1\n"


def obj_seeds():
    write("fuzz_obj", "wedge.obj", (ROOT / "docs/examples/wedge.obj").read_bytes())
    write("fuzz_obj", "full.obj", OBJ_FULL)
    write("fuzz_obj", "tetra_vn.obj", OBJ_TETRA_VN)
    write("fuzz_obj", "vt_only.obj", OBJ_VT_ONLY)
    write("fuzz_obj", "bad_normal_index.obj", OBJ_BAD_NORMALS)
    write("fuzz_obj", "bad_indices.obj", OBJ_BAD_INDICES)
    write("fuzz_obj", "nan.obj", OBJ_NAN)
    write("fuzz_obj", "nonmanifold.obj", OBJ_NONMANIFOLD)


# --------------------------------------------------------------------------------------- PLY

TETRA = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
TETRA_FACES = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
NORMALS = [(-0.577, -0.577, -0.577), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
UVS = [(0, 0), (1, 0), (0, 1), (1, 1)]

PLY_TYPES = {"char": "b", "uchar": "B", "short": "h", "ushort": "H", "int": "i", "uint": "I",
             "float": "f", "double": "d", "int8": "b", "uint8": "B", "int16": "h", "uint16": "H",
             "int32": "i", "uint32": "I", "float32": "f", "float64": "d"}


def ply(fmt, vtype="float", normals=False, uv=None, count_type="uchar", index_type="int",
        extra_element=False, quad=False, comment=True):
    """A tetrahedron (or a quad) as PLY in any of the three formats."""
    verts = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)] if quad else TETRA
    faces = [(0, 1, 2, 3)] if quad else TETRA_FACES
    props = [(vtype, "x"), (vtype, "y"), (vtype, "z")]
    if normals:
        props += [("float", "nx"), ("float", "ny"), ("float", "nz")]
    if uv:
        props += [("float", uv[0]), ("float", uv[1])]
    if extra_element:
        props += [("uchar", "red")]
    head = ["ply", "format %s 1.0" % fmt]
    if comment:
        head.append("comment made by tests/fuzz/make_seeds.py")
    head.append("element vertex %d" % len(verts))
    head += ["property %s %s" % p for p in props]
    head.append("element face %d" % len(faces))
    head.append("property list %s %s vertex_indices" % (count_type, index_type))
    if extra_element:
        head += ["element edge 1", "property int vertex1", "property int vertex2"]
    head.append("end_header")
    out = ("\n".join(head) + "\n").encode()
    rows = []
    for i, p in enumerate(verts):
        row = list(p)
        if normals:
            row += list(NORMALS[i])
        if uv:
            row += list(UVS[i])
        if extra_element:
            row += [200]
        rows.append(row)
    if fmt == "ascii":
        body = "".join(" ".join(str(v) for v in r) + "\n" for r in rows)
        body += "".join("%d %s\n" % (len(f), " ".join(map(str, f))) for f in faces)
        if extra_element:
            body += "0 1\n"
        return out + body.encode()
    e = "<" if fmt == "binary_little_endian" else ">"
    body = b""
    for r in rows:
        for (t, _), v in zip(props, r):
            body += struct.pack(e + PLY_TYPES[t], v)
    for f in faces:
        body += struct.pack(e + PLY_TYPES[count_type], len(f))
        body += b"".join(struct.pack(e + PLY_TYPES[index_type], i) for i in f)
    if extra_element:
        body += struct.pack(e + "ii", 0, 1)
    return out + body


def ply_seeds():
    write("fuzz_ply", "ascii.ply", ply("ascii"))
    write("fuzz_ply", "ascii_normals_uv.ply", ply("ascii", normals=True, uv=("u", "v"), quad=True))
    write("fuzz_ply", "ascii_extra.ply", ply("ascii", uv=("s", "t"), extra_element=True))
    write("fuzz_ply", "le.ply", ply("binary_little_endian", count_type="uchar", index_type="uint"))
    write("fuzz_ply", "le_normals_st.ply", ply("binary_little_endian", vtype="double", normals=True, uv=("s", "t")))
    write("fuzz_ply", "le_quad_extra.ply", ply("binary_little_endian", quad=True, extra_element=True, index_type="ushort"))
    write("fuzz_ply", "be.ply", ply("binary_big_endian", count_type="int", index_type="int"))
    write("fuzz_ply", "be_normals.ply", ply("binary_big_endian", normals=True, comment=False))
    write("fuzz_ply", "be_uv.ply", ply("binary_big_endian", uv=("u", "v"), count_type="ushort", index_type="uint"))
    # Malicious headers: counts that would take all memory, negative counts, a 255-gon, a truncated body.
    base = ply("binary_little_endian").decode("latin-1")
    write("fuzz_ply", "huge_faces.ply", base.replace("element face 4", "element face 4000000000").encode("latin-1"))
    write("fuzz_ply", "negative_faces.ply", base.replace("element face 4", "element face -1").encode("latin-1"))
    write("fuzz_ply", "negative_vertices.ply", ply("ascii").replace(b"element vertex 4", b"element vertex -1"))
    write("fuzz_ply", "huge_vertices.ply", ply("ascii").replace(b"element vertex 4", b"element vertex 18446744073709551615"))
    write("fuzz_ply", "truncated.ply", ply("binary_big_endian", normals=True)[:-7])
    big_list = ply("ascii").replace(b"3 0 2 1\n", b"255 0 2 1\n")
    write("fuzz_ply", "long_list.ply", big_list)
    write("fuzz_ply", "bad_index.ply", ply("ascii").replace(b"3 1 2 3\n", b"3 1 2 3000000000\n"))


# --------------------------------------------------------------------------------------- PNG

def png_chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xffffffff)


ADAM7 = [(0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2)]


def png(width, height, color_type, bit_depth, pixel, palette=None, interlace=False, extra=b""):
    """pixel(x, y) -> tuple of samples. Filter type 0 except for a Paeth/Sub row here and there."""
    spp = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}[color_type]

    def rows(xs, ys):
        raw = b""
        for n, y in enumerate(ys):
            bits = []
            for x in xs:
                bits += list(pixel(x, y))
            if bit_depth == 8:
                line = bytes(bits)
            elif bit_depth == 16:
                line = b"".join(struct.pack(">H", v) for v in bits)
            else:  # packed 1/2/4-bit samples
                per = 8 // bit_depth
                line = b""
                for i in range(0, len(bits), per):
                    chunk = bits[i:i + per] + [0] * (per - len(bits[i:i + per]))
                    b = 0
                    for v in chunk:
                        b = (b << bit_depth) | v
                    line += bytes([b])
            if n % 2 == 1 and bit_depth >= 8:  # Sub filter on odd rows
                bpp = spp * bit_depth // 8
                line = bytes((line[i] - (line[i - bpp] if i >= bpp else 0)) & 255 for i in range(len(line)))
                raw += b"\x01" + line
            else:
                raw += b"\x00" + line
        return raw

    if interlace:
        raw = b""
        for x0, y0, dx, dy in ADAM7:
            xs, ys = list(range(x0, width, dx)), list(range(y0, height, dy))
            if xs and ys:
                raw += rows(xs, ys)
    else:
        raw = rows(range(width), range(height))
    ihdr = struct.pack(">IIBBBBB", width, height, bit_depth, color_type, 0, 0, 1 if interlace else 0)
    out = b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", ihdr)
    if palette:
        out += png_chunk(b"PLTE", b"".join(bytes(c) for c in palette))
    out += extra
    out += png_chunk(b"IDAT", zlib.compress(raw, 9)) + png_chunk(b"IEND", b"")
    return out


def png_seeds():
    write("fuzz_png", "rgb_4x3.png", png(4, 3, 2, 8, lambda x, y: (60 * x, 80 * y, 128)))
    write("fuzz_png", "rgba_3x2.png", png(3, 2, 6, 8, lambda x, y: (255, 100 * x, 50, 255 - 100 * y)))
    write("fuzz_png", "gray_2x2.png", png(2, 2, 0, 8, lambda x, y: (x * 200 + y * 50,),
                                          extra=png_chunk(b"gAMA", struct.pack(">I", 100000))))
    write("fuzz_png", "gray_alpha_1x1.png", png(1, 1, 4, 8, lambda x, y: (128, 200)))
    write("fuzz_png", "rgb16_2x2.png", png(2, 2, 2, 16, lambda x, y: (65535 * x, 30000, 1000 * y),
                                           extra=png_chunk(b"sRGB", b"\x00")))
    write("fuzz_png", "palette4_5x3.png", png(5, 3, 3, 4, lambda x, y: ((x + y) % 3,),
                                              palette=[(255, 0, 0), (0, 255, 0), (0, 0, 255)]))
    write("fuzz_png", "gray1_9x2.png", png(9, 2, 0, 1, lambda x, y: ((x + y) % 2,)))
    write("fuzz_png", "interlaced_9x9.png", png(9, 9, 2, 8, lambda x, y: (x * 28, y * 28, 7), interlace=True))
    # Malicious: a header declaring 30000 x 30000 (beyond the side limit) over a 1-pixel IDAT, and
    # one that is exactly at the limit on one side with a zero-sized other side.
    one = png(1, 1, 2, 8, lambda x, y: (1, 2, 3))
    ihdr = struct.pack(">IIBBBBB", 30000, 30000, 8, 2, 0, 0, 0)
    huge = one[:8] + png_chunk(b"IHDR", ihdr) + one[33:]
    write("fuzz_png", "huge_header.png", huge)
    ihdr = struct.pack(">IIBBBBB", 16384, 0, 8, 2, 0, 0, 0)
    write("fuzz_png", "zero_height.png", one[:8] + png_chunk(b"IHDR", ihdr) + one[33:])
    write("fuzz_png", "truncated.png", png(4, 3, 2, 8, lambda x, y: (1, 2, 3))[:-30])


# --------------------------------------------------------------------------------------- EXR

def exr_attr(name, kind, data):
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(data)) + data


def interleave_predict(raw):
    t = raw[0::2] + raw[1::2]
    out = bytearray(t)
    for i in range(len(t) - 1, 0, -1):
        out[i] = (t[i] - t[i - 1] + 128) & 255
    return bytes(out)


def rle(data):
    out = bytearray()
    i = 0
    while i < len(data):
        run = 1
        while i + run < len(data) and data[i + run] == data[i] and run < 128:
            run += 1
        if run >= 3:
            out += struct.pack("<bB", run - 1, data[i])
            i += run
        else:
            j = i
            while j < len(data) and j - i < 127 and not (j + 2 < len(data) and data[j] == data[j + 1] == data[j + 2]):
                j += 1
            out += struct.pack("<b", -(j - i)) + data[i:j]
            i = j
    return bytes(out)


def exr(width, height, channels, pixel, compression=0, data_window=None):
    """Scanline EXR. channels: [(name, type)] with type 1 = half, 2 = float; pixel(x, y, name)."""
    channels = sorted(channels)
    chlist = b"".join(n.encode() + b"\0" + struct.pack("<iB3xii", t, 0, 1, 1) for n, t in channels) + b"\0"
    dw = data_window or (0, 0, width - 1, height - 1)
    header = b"\x76\x2f\x31\x01" + struct.pack("<I", 2)
    header += exr_attr("channels", "chlist", chlist)
    header += exr_attr("compression", "compression", bytes([compression]))
    header += exr_attr("dataWindow", "box2i", struct.pack("<4i", *dw))
    header += exr_attr("displayWindow", "box2i", struct.pack("<4i", 0, 0, width - 1, height - 1))
    header += exr_attr("lineOrder", "lineOrder", b"\0")
    header += exr_attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
    header += exr_attr("screenWindowCenter", "v2f", struct.pack("<2f", 0, 0))
    header += exr_attr("screenWindowWidth", "float", struct.pack("<f", 1.0))
    header += b"\0"
    lines_per_chunk = {0: 1, 1: 1, 2: 1, 3: 16}[compression]
    chunks = []
    for y0 in range(0, height, lines_per_chunk):
        raw = b""
        for y in range(y0, min(height, y0 + lines_per_chunk)):
            for n, t in channels:
                fmt = "<e" if t == 1 else "<f"
                raw += b"".join(struct.pack(fmt, pixel(x, y, n)) for x in range(width))
        data = raw
        if compression == 1:
            data = rle(interleave_predict(raw))
        elif compression in (2, 3):
            data = zlib.compress(interleave_predict(raw), 9)
        if len(data) >= len(raw):
            data = raw  # stored uncompressed when compression does not help (as OpenEXR does)
        chunks.append(struct.pack("<ii", y0, len(data)) + data)
    offsets = []
    pos = len(header) + 8 * len(chunks)
    for c in chunks:
        offsets.append(pos)
        pos += len(c)
    return header + b"".join(struct.pack("<Q", o) for o in offsets) + b"".join(chunks)


def exr_seeds():
    rgb_half = [("R", 1), ("G", 1), ("B", 1)]
    grad = lambda x, y, n: {"R": x / 4.0, "G": y / 4.0, "B": 0.5, "A": 1.0, "Y": 0.25 * (x + y)}[n]
    flat = lambda x, y, n: {"R": 0.5, "G": 0.25, "B": 2.0, "A": 1.0}[n]
    write("fuzz_exr", "half_rgb_none_3x2.exr", exr(3, 2, rgb_half, grad))
    write("fuzz_exr", "float_rgba_none_2x2.exr", exr(2, 2, [("R", 2), ("G", 2), ("B", 2), ("A", 2)], grad))
    write("fuzz_exr", "half_rgb_rle_16x2.exr", exr(16, 2, rgb_half, flat, compression=1))
    write("fuzz_exr", "half_rgba_zips_16x2.exr", exr(16, 2, rgb_half + [("A", 1)], flat, compression=2))
    write("fuzz_exr", "float_rgb_zip_16x17.exr", exr(16, 17, [("R", 2), ("G", 2), ("B", 2)], flat, compression=3))
    write("fuzz_exr", "gray_y_4x1.exr", exr(4, 1, [("Y", 1)], grad))
    write("fuzz_exr", "layers_2x1.exr", exr(2, 1, [("R", 1), ("G", 1), ("B", 1), ("albedo.R", 1), ("depth.Z", 2)],
                                            lambda x, y, n: 0.5))
    # Malicious: a data window of 30000 x 30000 over a 1-line file, and an inverted one.
    write("fuzz_exr", "huge_window.exr", exr(2, 1, rgb_half, grad, data_window=(0, 0, 29999, 29999)))
    write("fuzz_exr", "inverted_window.exr", exr(2, 1, rgb_half, grad, data_window=(5, 5, 0, 0)))


# --------------------------------------------------------------------------------------- HDR

def rgbe(r, g, b):
    import math
    v = max(r, g, b)
    if v < 1e-32:
        return bytes(4)
    m, e = math.frexp(v)
    s = m * 256.0 / v
    return bytes([int(r * s), int(g * s), int(b * s), e + 128])


def hdr(width, height, pixel, rle_lines=False, magic=b"#?RADIANCE", res=None):
    out = magic + b"\nFORMAT=32-bit_rle_rgbe\nEXPOSURE=1.0\n\n"
    out += (res or ("-Y %d +X %d" % (height, width))).encode() + b"\n"
    for y in range(height):
        line = [rgbe(*pixel(x, y)) for x in range(width)]
        if not rle_lines:
            out += b"".join(line)
            continue
        out += bytes([2, 2, width >> 8, width & 255])
        for c in range(4):
            comp = bytes(p[c] for p in line)
            i = 0
            while i < len(comp):
                run = 1
                while i + run < len(comp) and comp[i + run] == comp[i] and run < 127:
                    run += 1
                if run >= 3:
                    out += bytes([128 + run, comp[i]])
                    i += run
                else:
                    j = i
                    while j < len(comp) and j - i < 128 and not (j + 2 < len(comp) and comp[j] == comp[j + 1] == comp[j + 2]):
                        j += 1
                    out += bytes([j - i]) + comp[i:j]
                    i = j
    return out


def hdr_seeds():
    write("fuzz_hdr", "flat_3x2.hdr", hdr(3, 2, lambda x, y: (x * 0.5, y * 2.0, 0.25)))
    write("fuzz_hdr", "rle_16x2.hdr", hdr(16, 2, lambda x, y: (1.0, 0.5 if x < 8 else 4.0, x * 0.1), rle_lines=True))
    write("fuzz_hdr", "rgbe_magic_2x2.hdr", hdr(2, 2, lambda x, y: (100.0, 0.001, 0.0), magic=b"#?RGBE"))
    write("fuzz_hdr", "flipped_2x2.hdr", hdr(2, 2, lambda x, y: (1, 1, 1), res="+Y 2 +X 2"))
    # Malicious: huge declared resolution over a short body; a lying RLE run length.
    write("fuzz_hdr", "huge_header.hdr", hdr(2, 1, lambda x, y: (1, 1, 1), res="-Y 30000 +X 30000"))
    bad = bytearray(hdr(16, 1, lambda x, y: (1.0, 1.0, 1.0), rle_lines=True))
    head_end = bad.index(b"+X 16\n") + 6
    bad[head_end + 4] = 255  # a run of 127 in a 16-pixel line
    write("fuzz_hdr", "bad_rle_run.hdr", bytes(bad))


# --------------------------------------------------------------------------------------- job JSON

JOB_MALICIOUS = {
    "bad_enum.json": '{"name": "x", "zoo": "cornell", "render": {"estimator": 99, "spp": -4}}\n',
    "deep.json": '{"name": "deep", "zoo": "cornell", "optimization": {"parameters": [' +
                 ",".join('{"name": "materials/red/albedo", "initial": 1e308, "learning_rate": -0}' for _ in range(20)) +
                 '], "steps": 2147483647, "seed": "18446744073709551615"}}\n',
    "unknown_field.json": '{"name": "x", "scene": {"shapes": [{"name": "a", "bogus": 1}]}}\n',
    "nan.json": '{"name": "n", "zoo": "cornell", "optimization": {"parameters": [{"name": "materials/red/albedo", '
                '"initial": "NaN", "learning_rate": "Infinity"}]}}\n',
}


def job_seeds(invr):
    for p in ["tabletop.json", "tabletop_optimize.json"]:
        write("fuzz_job_json", p, (ROOT / "docs/examples" / p).read_bytes())
    if invr:
        for name in ["cornell", "oxalis", "mirror", "backlit"]:
            write("fuzz_job_json", "zoo_%s.json" % name, subprocess.check_output([invr, "example", name]))
    for name, text in JOB_MALICIOUS.items():
        write("fuzz_job_json", name, text)


def job_dictionary():
    """Every field name and enum value of the job schema, as JSON strings (libFuzzer -dict format)."""
    words = set()
    for proto in [ROOT / "proto/invr/v1/scene.proto", ROOT / "proto/invr/v1/job.proto"]:
        for line in proto.read_text().splitlines():
            line = line.split("//")[0]
            m = re.match(r"\s*(?:repeated\s+|optional\s+)?[\w.]+\s+(\w+)\s*=\s*\d+", line)
            if m and not line.strip().startswith(("option", "reserved")):
                words.add(m.group(1))
            m = re.match(r"\s*([A-Z][A-Z0-9_]+)\s*=\s*-?\d+\s*;", line)
            if m:
                words.add(m.group(1))
    lines = ["# Field names and enum values of proto/invr/v1/{scene,job}.proto (written by make_seeds.py).",
             'kw_open="{"', 'kw_close="}"', 'kw_colon=": "', 'kw_true="true"', 'kw_null="null"',
             'kw_nan="\\"NaN\\""', 'kw_inf="\\"-Infinity\\""', 'kw_big="1e309"', 'kw_u64="\\"18446744073709551615\\""']
    lines += ['"\\"%s\\""' % w for w in sorted(words)]
    (ROOT / "tests/fuzz/job_json.dict").write_text("\n".join(lines) + "\n")


# --------------------------------------------------------------------------------------- Mitsuba XML

MITSUBA_CAMERA = """<default name="spp" value="4"/>
<integrator type="path"><integer name="max_depth" value="$spp"/><integer name="rr_depth" value="3"/></integrator>
<sensor type="perspective" id="cam"><float name="fov" value="40"/><string name="fov_axis" value="smaller"/>
<transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
<sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
<film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/><rfilter type="gaussian"/></film></sensor>
"""

MITSUBA_SEEDS = {
    "room.xml": """<bsdf type="twosided" id="w"><bsdf type="diffuse"><rgb name="reflectance" value="0.5, 0.25, 0.125"/></bsdf></bsdf>
<shape type="rectangle" id="floor"><transform name="to_world"><scale value="2"/><rotate x="1" angle="-90"/><translate y="-1"/></transform><ref id="w"/></shape>
<shape type="rectangle" id="lamp"><transform name="to_world"><scale x="0.5" y="0.25"/><rotate value="1 0 0" angle="90"/><translate value="0 1.5 0"/></transform>
<emitter type="area"><spectrum name="radiance" value="5"/></emitter></shape>""",
    "objects.xml": """<shape type="cube"><transform name="to_world"><matrix value="0.5 0 0 0 0 0.5 0 0 0 0 0.5 0 0 0 0 1"/></transform>
<bsdf type="roughconductor"><string name="material" value="Au"/><float name="alpha" value="0.2"/><string name="distribution" value="ggx"/></bsdf></shape>
<shape type="sphere"><point name="center" x="1" y="0" z="0"/><float name="radius" value="0.25"/><bsdf type="roughplastic"><float name="alpha" value="0.1"/><string name="int_ior" value="bk7"/></bsdf></shape>
<shape type="disk"><boolean name="flip_normals" value="true"/><bsdf type="conductor"><rgb name="eta" value="0.2 0.9 1.1"/><rgb name="k" value="3.9 2.4 2.1"/></bsdf></shape>
<shape type="sphere"><bsdf type="dielectric"><float name="int_ior" value="1.33"/></bsdf></shape>
<shape type="cube"><bsdf type="plastic"/></shape>
<emitter type="point"><point name="position" value="0 2 0"/><rgb name="intensity" value="10"/></emitter>
<emitter type="spot"><transform name="to_world"><lookat origin="0 3 0" target="0 0 0" up="0 0 1"/></transform><float name="cutoff_angle" value="25"/></emitter>
<emitter type="constant"><rgb name="radiance" value="0.1"/></emitter>""",
    "errors.xml": """<bsdf type="twosided" id="a"><ref id="b"/></bsdf><bsdf type="twosided" id="b"><ref id="a"/></bsdf>
<shape type="obj"><string name="filename" value="missing.obj"/><ref id="a"/></shape><emitter type="constant"/>""",
}


def mitsuba_seeds():
    for name, body in MITSUBA_SEEDS.items():
        write("fuzz_mitsuba_xml", name, '<scene version="3.0.0">\n' + MITSUBA_CAMERA + body + "\n</scene>\n")
    write("fuzz_mitsuba_xml", "include_devzero.xml", '<scene version="3.0.0"><include filename="/dev/zero"/></scene>\n')
    words = ["<scene", "</scene>", 'version="3.0.0"', "<default", "<include", "<ref", "<shape", "<bsdf", "<emitter", "<sensor",
             "<film", "<sampler", "<rfilter", "<integrator", "<texture", "<transform", "<translate", "<rotate", "<scale",
             "<matrix", "<lookat", "<float", "<integer", "<boolean", "<string", "<rgb", "<spectrum", "<point", "<vector",
             "/>", "</shape>", "</bsdf>", "type=", "name=", "value=", "id=", "angle=", "origin=", "target=", "up=", "x=",
             "filename=", "$"]
    lines = ["# Mitsuba 3 XML tokens (written by make_seeds.py)."] + ['"%s"' % w.replace('"', '\\"') for w in words]
    (ROOT / "tests/fuzz/mitsuba_xml.dict").write_text("\n".join(lines) + "\n")


# --------------------------------------------------------------------------------------- TaskResult

# The fixed tasks of fuzz_task_result.cc: job "job-000001"; task 1 = GRADIENT views {0,1} on shard 0;
# task 2 = GRADIENT render-only views {1} on shard 1; task 3 = FINAL_RENDER view {0} on shard 0.
# The job has 12 parameters and an 8 x 6 film.
def pixels(n, v):
    return " ".join("pixels: %g" % (v + 0.001 * i) for i in range(n))


TASK_RESULTS = {
    "gradient.txtpb": 'task_id: 1 job_id: "job-000001" shard: 0 ' +
                      " ".join("gradient: %g" % (0.1 * i - 0.5) for i in range(12)) +
                      " stats { loss: 0.25 seconds_primal: 0.01 seconds_derivative: 0.02 reservoirs: 96 sum_m: 216 shading_points: 48"
                      ' rays { camera: 96 shadow: 200 } boundary { key: "primary" value { seconds: 0.01 samples: 256'
                      ' counters { key: "edges" value: 7 } } } }',
    "render_only.txtpb": 'task_id: 2 job_id: "job-000001" shard: 1 stats { seconds_primal: 0.01 } rebuilt: true seconds_session: 0.5',
    "final_render.txtpb": 'task_id: 3 job_id: "job-000001" shard: 0 ' +
                          "renders { width: 8 height: 6 channels: 3 %s } " % pixels(144, 0.5) +
                          "renders { width: 8 height: 6 channels: 3 %s }" % pixels(144, 0.25),
    "spec_unknown.txtpb": 'task_id: 1 job_id: "job-000001" shard: 0 spec_unknown: true',
    "error.txtpb": 'task_id: 1 job_id: "job-000001" shard: 0 error: "materials/red: texture not found" input_error: true',
    # Malicious: statistics with a negative timing and too many boundary terms; one gradient value too many; a render whose pixels do not match its size; a render
    # larger than the film; negative sizes; more renders than views.
    "stats_bad.txtpb": 'task_id: 1 job_id: "job-000001" ' + " ".join("gradient: 1" for _ in range(12)) +
                       " stats { seconds_boundary: -1 " + " ".join('boundary { key: "t%d" value { samples: 1 } }' % i for i in range(70)) + " }",
    "gradient_13.txtpb": 'task_id: 1 job_id: "job-000001" ' + " ".join("gradient: 1" for _ in range(13)),
    "render_short.txtpb": 'task_id: 3 job_id: "job-000001" renders { width: 8 height: 6 channels: 3 %s } '
                          'renders { width: 8 height: 6 channels: 3 %s }' % (pixels(10, 1), pixels(144, 1)),
    "render_big.txtpb": 'task_id: 3 job_id: "job-000001" renders { width: 65536 height: 65536 channels: 4 pixels: 1 } '
                        'renders { width: -8 height: -6 channels: 3 %s }' % pixels(144, 1),
    "render_many.txtpb": 'task_id: 3 job_id: "job-000001" ' + " ".join(
        "renders { width: 8 height: 6 channels: 4 %s }" % pixels(192, 0) for _ in range(3)),
}


def task_result_seeds():
    protoc = shutil.which("protoc")
    if not protoc:
        print("make_seeds: no protoc; TaskResult seeds left as they are")
        return
    for name, text in TASK_RESULTS.items():
        data = subprocess.run([protoc, "--encode=invr.v1.TaskResult", "-I", str(ROOT / "proto"), "invr/v1/service.proto"],
                              input=text.encode(), capture_output=True, check=True).stdout
        write("fuzz_task_result", name.replace(".txtpb", ".bin"), data)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--invr", help="a built invr binary, for the zoo's example jobs")
    args = ap.parse_args()
    obj_seeds()
    ply_seeds()
    png_seeds()
    exr_seeds()
    hdr_seeds()
    job_seeds(args.invr)
    job_dictionary()
    task_result_seeds()
    mitsuba_seeds()
    for d in sorted(CORPUS.iterdir()):
        files = list(d.iterdir())
        print("%-18s %2d seeds, %6d bytes, largest %5d" % (d.name, len(files), sum(f.stat().st_size for f in files),
                                                           max(f.stat().st_size for f in files)))


if __name__ == "__main__":
    main()
