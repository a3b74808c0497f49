"""The .pmwm file and the key file as untrusted input: exact round trips, and nothing but
PMFormatError / KeyFileError for truncated, corrupted, forged or future files."""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import struct
import tracemalloc

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import meshes
import pmwm
from pmwm.errors import KeyFileError, OutputExistsError, PmwmError, PMFormatError
from pmwm.api import load_key_data
from pmwm.key import WatermarkKey
from pmwm.progressive import MAGIC, VERSION, from_bytes, read_pm, to_bytes, write_pm
from pmwm.progressive import ENDS_SHIFT, FLAG_SINGLE, ProgressiveMesh, build_progressive_mesh

COW = meshes.mesh_file("blob.off")  # a small closed organic mesh (2.9k vertices), generated
# The header as documented in pmwm/progressive/fileformat.py: magic, version u16, flags u16, then
# n_base_vertices, n_base_faces, n_records, n_levels, reserved as u32; a SHA-256 ends the file.
HEADER = struct.Struct("<8sHHIIIII")
FIELDS = ("magic", "version", "flags", "nb", "fb", "nr", "nl", "reserved")
DIGEST = 32
MB = 1 << 20
HYPO = settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])


# ---------------------------------------------------------------- sample progressive meshes


def _icosphere():
    s = trimesh.creation.icosphere(subdivisions=1)
    return np.asarray(s.vertices, np.float64), np.asarray(s.faces, np.int64)


@functools.cache
def _open_pm() -> ProgressiveMesh:
    """Tiny open mesh (boundary splits add one face), float32-exact positions."""
    V, F = _icosphere()
    V = V.astype(np.float32).astype(np.float64)
    F = F[V[F].mean(axis=1)[:, 2] <= 0.6]  # cut a cap off: the mesh gets a boundary
    used = np.unique(F)
    remap = np.full(len(V), -1)
    remap[used] = np.arange(len(used))
    pm, _ = build_progressive_mesh(V[used], remap[F], base_vertices=6)
    assert pm.float32 and np.any(pm.flags & FLAG_SINGLE) and len(pm.level_records) > 3
    return pm


@functools.cache
def _closed_pm() -> ProgressiveMesh:
    """Tiny closed mesh whose positions need float64."""
    V, F = _icosphere()
    V = V + 1e-9 * np.arange(len(V))[:, None]
    pm, _ = build_progressive_mesh(V, F, base_vertices=6)
    assert not pm.float32
    return pm


@functools.cache
def _cow():
    """A realistic marked mesh (2.9k vertices, read from a file): its progressive mesh, key and geometry."""
    src = pmwm.read_mesh(COW)
    return pmwm.embed(src.vertices, src.faces, pmwm.EmbedOptions(payload="test", seed=1))


# Plain functions (cached) rather than fixtures alone, so that hypothesis tests can use them
# without printing a whole mesh in every failure report.
@pytest.fixture(scope="module")
def open_pm() -> ProgressiveMesh:
    return _open_pm()


@pytest.fixture(scope="module")
def closed_pm() -> ProgressiveMesh:
    return _closed_pm()


@pytest.fixture(scope="module")
def cow():
    return _cow()


@pytest.fixture(scope="module", params=["open_pm", "closed_pm", "cow"])
def any_pm(request) -> ProgressiveMesh:
    got = request.getfixturevalue(request.param)
    return got.pm if request.param == "cow" else got


def _reseal(data: bytes) -> bytes:
    """Recompute the trailing checksum, so that only the deliberate inconsistency remains."""
    body = bytes(data[:-DIGEST])
    return body + hashlib.sha256(body).digest()


def _patch_header(data: bytes, reseal: bool = True, **changes) -> bytes:
    values = dict(zip(FIELDS, HEADER.unpack_from(data, 0)))
    values.update(changes)
    out = HEADER.pack(*(values[f] for f in FIELDS)) + data[HEADER.size :]
    return _reseal(out) if reseal else out


def _same_pm(a: ProgressiveMesh, b: ProgressiveMesh) -> None:
    for name in ("base_vertices", "base_faces", "pos", "v", "mask", "flags", "level_records"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.shape == y.shape and np.array_equal(x, y), name
    assert a.float32 == b.float32 and a.end_ranks == b.end_ranks


def _levels_to_check(pm: ProgressiveMesh) -> list[int]:
    ks = {0, pm.n_records, *pm.level_records.tolist(), *(pm.level_records - 1).clip(0).tolist()}
    return sorted(ks)


def _load_or_reject(data: bytes) -> ProgressiveMesh | None:
    """None if the bytes are refused with PMFormatError; a parsed PM must decode (base, a prefix
    that ends inside a level, everything)."""
    try:
        pm = from_bytes(data)
    except PMFormatError:
        return None
    for k in sorted({0, pm.n_records // 2 + 1, pm.n_records}):
        V, F = pm.decode(records=k)
        assert V.shape == (pm.n_base_vertices + k, 3)
        assert len(F) == 0 or (F.min() >= 0 and F.max() < len(V))
    return pm


def _rebuild(pm: ProgressiveMesh, **changes) -> bytes:
    """A file for ``pm`` with some arrays replaced (written by to_bytes: valid checksum)."""
    fields = {f.name: getattr(pm, f.name) for f in dataclasses.fields(pm)}
    fields.update({k: np.array(v, copy=True) if isinstance(v, np.ndarray) else v for k, v in changes.items()})
    fields["vertex_order"] = fields["face_order"] = None
    return to_bytes(ProgressiveMesh(**fields))


# ---------------------------------------------------------------- round trips


def test_round_trip_is_exact(any_pm, tmp_path):
    data = to_bytes(any_pm)
    back = from_bytes(data)
    _same_pm(any_pm, back)
    assert to_bytes(back) == data  # byte-stable
    for k in _levels_to_check(any_pm):
        V0, F0 = any_pm.decode(records=k)
        V1, F1 = back.decode(records=k)
        assert np.array_equal(V0, V1) and np.array_equal(F0, F1), k
    path = tmp_path / "m.pmwm"
    write_pm(path, any_pm)
    assert path.read_bytes() == data
    _same_pm(any_pm, read_pm(path))


def test_the_file_version_follows_the_end_ranks(any_pm):
    """pmwm writes version 2 (the masks name each arc's end faces); a progressive mesh without them,
    as read from a version-1 file, is written as version 1 and reads back as it was."""
    assert any_pm.end_ranks
    assert HEADER.unpack_from(to_bytes(any_pm), 0)[1] == VERSION == 2
    plain = dataclasses.replace(any_pm, end_ranks=False)
    data = to_bytes(plain)
    assert HEADER.unpack_from(data, 0)[1] == 1
    back = from_bytes(data)
    _same_pm(plain, back)
    V0, F0 = any_pm.decode()
    V1, F1 = back.decode()
    assert np.array_equal(V0, V1) and np.array_equal(F0, F1)


def test_full_decode_of_the_file_is_the_marked_mesh(cow):
    """What a user ships (the .pmwm) rebuilds exactly the marked mesh they verified."""
    pm = from_bytes(to_bytes(cow.pm))
    V, F = pm.decode()
    order = cow.pm.vertex_order
    assert np.array_equal(V, cow.vertices[order])
    inv = np.empty_like(order)
    inv[order] = np.arange(len(order))
    tri = np.sort(inv[cow.faces], axis=1)
    assert np.array_equal(np.unique(np.sort(F, axis=1), axis=0), np.unique(tri, axis=0))


def test_write_pm_refuses_an_existing_file_unless_forced(open_pm, closed_pm, tmp_path):
    path = tmp_path / "m.pmwm"
    path.write_bytes(b"precious")
    with pytest.raises(OutputExistsError):
        write_pm(path, open_pm)
    assert path.read_bytes() == b"precious"
    write_pm(path, closed_pm, force=True)
    _same_pm(closed_pm, read_pm(path))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.pmwm"]


# ---------------------------------------------------------------- truncation and corruption


def test_every_truncation_of_a_tiny_file_is_refused(open_pm):
    data = to_bytes(open_pm)
    for n in range(len(data)):
        with pytest.raises(PMFormatError):
            from_bytes(data[:n])
    with pytest.raises(PMFormatError, match="truncated|padded"):
        from_bytes(data + b"\0")


def test_truncations_of_a_real_file_are_refused(cow, tmp_path):
    data = to_bytes(cow.pm)
    rng = np.random.default_rng(0)
    cuts = set(rng.integers(0, len(data), 300).tolist()) | {0, 1, 8, HEADER.size, len(data) - DIGEST, len(data) - 1}
    for n in sorted(cuts):
        with pytest.raises(PMFormatError):
            from_bytes(data[:n])
    path = tmp_path / "cut.pmwm"
    for n in sorted(cuts)[::30]:
        path.write_bytes(data[:n])
        with pytest.raises(PMFormatError):
            read_pm(path)


def test_every_single_bit_flip_of_a_tiny_file_is_refused(open_pm):
    data = to_bytes(open_pm)
    for i in range(len(data)):
        for bit in range(8):
            bad = bytearray(data)
            bad[i] ^= 1 << bit
            with pytest.raises(PMFormatError):
                from_bytes(bytes(bad))


def test_sampled_bit_flips_of_a_real_file_are_refused(cow, tmp_path):
    data = to_bytes(cow.pm)
    rng = np.random.default_rng(1)
    path = tmp_path / "flip.pmwm"
    for j, (i, bit) in enumerate(zip(rng.integers(0, len(data), 300), rng.integers(0, 8, 300))):
        bad = bytearray(data)
        bad[i] ^= 1 << int(bit)
        with pytest.raises(PMFormatError):
            from_bytes(bytes(bad))
        if j % 50 == 0:
            path.write_bytes(bytes(bad))
            with pytest.raises(PMFormatError):
                read_pm(path)


def test_wrong_magic_is_refused(open_pm, tmp_path):
    data = to_bytes(open_pm)
    with pytest.raises(PMFormatError, match="magic"):
        from_bytes(_patch_header(data, magic=b"\x89PNG\r\n\x1a\n"))
    mesh = tmp_path / "mesh.pmwm"  # a mesh file given where a .pmwm is expected
    mesh.write_bytes(COW.read_bytes())
    with pytest.raises(PMFormatError):
        read_pm(mesh)


@pytest.mark.parametrize("version", [VERSION + 1, 0xFFFF])
def test_future_version_asks_for_an_upgrade(open_pm, version):
    data = _patch_header(to_bytes(open_pm), version=version)
    with pytest.raises(PMFormatError, match="upgrade"):
        from_bytes(data)


def test_version_zero_and_unknown_flags_are_refused(open_pm):
    data = to_bytes(open_pm)
    with pytest.raises(PMFormatError, match="version"):
        from_bytes(_patch_header(data, version=0))
    with pytest.raises(PMFormatError, match="flag"):
        from_bytes(_patch_header(data, flags=4))


@pytest.mark.parametrize("field", ["nb", "fb", "nr", "nl"])
@pytest.mark.parametrize("reseal", [False, True])
def test_a_header_promising_a_billion_records_is_refused_without_allocating(open_pm, tmp_path, field, reseal):
    data = _patch_header(to_bytes(open_pm), reseal=reseal, **{field: 1_000_000_000})
    path = tmp_path / "huge.pmwm"
    path.write_bytes(data)
    tracemalloc.start()
    try:
        with pytest.raises(PMFormatError, match="truncated|promises"):
            from_bytes(data)
        with pytest.raises(PMFormatError, match="truncated|promises"):
            read_pm(path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 4 * MB


def test_files_that_are_not_files_are_refused(tmp_path):
    with pytest.raises(PMFormatError, match="does not exist"):
        read_pm(tmp_path / "missing.pmwm")
    with pytest.raises(PMFormatError, match="directory"):
        read_pm(tmp_path)
    (tmp_path / "empty.pmwm").write_bytes(b"")
    with pytest.raises(PMFormatError):
        read_pm(tmp_path / "empty.pmwm")


# ---------------------------------------------------------------- consistent checksum, inconsistent content


def _level_with_two_records(pm: ProgressiveMesh) -> int:
    starts = np.r_[0, pm.level_records[:-1]]
    return int(starts[np.flatnonzero(pm.level_records - starts >= 2)[0]])


def test_a_record_splitting_a_vertex_that_does_not_exist_yet_is_refused(open_pm):
    r = open_pm.n_records // 2
    v = open_pm.v.copy()
    v[r] = open_pm.n_base_vertices + r  # the vertex this very record would add
    with pytest.raises(PMFormatError, match="inconsistent"):
        from_bytes(_rebuild(open_pm, v=v))
    v[r] = open_pm.n_vertices + 5
    with pytest.raises(PMFormatError, match="inconsistent"):
        from_bytes(_rebuild(open_pm, v=v))


def test_a_record_splitting_a_vertex_added_in_its_own_level_is_refused(cow):
    """The records of one level are independent splits applied together: a record cannot split
    a vertex that an earlier record of the same level adds. Such a file is not a valid .pmwm."""
    pm = cow.pm
    a = _level_with_two_records(pm)
    v = pm.v.copy()
    v[a + 1] = pm.n_base_vertices + a  # added by record a, same level
    with pytest.raises(PMFormatError, match="inconsistent"):
        from_bytes(_rebuild(pm, v=v))


@pytest.mark.parametrize(
    "case",
    ["levels swapped", "level ends early", "level starts at zero", "face to missing vertex", "nan base", "nan record"],
)
def test_inconsistent_tables_with_a_valid_checksum_are_refused(open_pm, case):
    pm = open_pm
    lv = pm.level_records.copy()
    change: dict = {}
    if case == "levels swapped":
        lv[[1, 2]] = lv[[2, 1]]
        change["level_records"] = lv
    elif case == "level ends early":
        lv[-1] = pm.n_records - 1
        change["level_records"] = lv
    elif case == "level starts at zero":
        lv[0] = 0
        change["level_records"] = lv
    elif case == "face to missing vertex":
        bf = pm.base_faces.copy()
        bf[0, 1] = pm.n_base_vertices
        change["base_faces"] = bf
    elif case == "nan base":
        bv = pm.base_vertices.copy()
        bv[0, 0] = np.nan
        change["base_vertices"] = bv
    else:
        pos = pm.pos.copy()
        pos[-1, 2] = np.inf
        change["pos"] = pos
    with pytest.raises(PMFormatError, match="inconsistent"):
        from_bytes(_rebuild(pm, **change))


@pytest.mark.parametrize("shift", [(2, 0, -1, 0), (0, 2, -1, 0), (0, 0, -1, 6), (0, 0, 1, -6), (-2, 0, 1, 0)])
def test_header_counts_that_still_add_up_to_the_file_size_are_refused(open_pm, shift):
    """Counts changed so that the size check passes (checksum recomputed): the tables no longer agree."""
    data = to_bytes(open_pm)
    h = dict(zip(FIELDS, HEADER.unpack_from(data, 0)))
    dnb, dfb, dnr, dnl = shift  # 2 vertices (24 B) or 2 faces (24 B) or 6 levels (24 B) for 1 record (24 B)
    patched = _patch_header(data, nb=h["nb"] + dnb, fb=h["fb"] + dfb, nr=h["nr"] + dnr, nl=h["nl"] + dnl)
    assert len(patched) == len(data)
    assert _load_or_reject(patched) is None


# ---------------------------------------------------------------- fuzzing the .pmwm reader

_edit = st.tuples(st.sampled_from(["set", "insert", "delete"]), st.integers(0, 1 << 20), st.integers(0, 255))


@HYPO
@given(data=st.binary(max_size=4096), with_magic=st.booleans())
def test_random_bytes_are_refused_with_pmformaterror(data, with_magic):
    if with_magic:
        data = MAGIC + struct.pack("<H", VERSION) + data
    with pytest.raises(PMFormatError):
        from_bytes(data)


@HYPO
@given(edits=st.lists(_edit, min_size=1, max_size=6), reseal=st.booleans(), which=st.sampled_from(["open", "closed"]))
def test_random_mutations_of_a_valid_file_never_raise_anything_else(edits, reseal, which):
    good = to_bytes(_open_pm() if which == "open" else _closed_pm())
    buf = bytearray(good)
    for op, pos, value in edits:
        i = pos % (len(buf) + 1)
        if op == "insert":
            buf.insert(i, value)
        elif len(buf) and op == "set":
            buf[i % len(buf)] = value
        elif len(buf):
            del buf[i % len(buf)]
    data = _reseal(bytes(buf)) if reseal and len(buf) >= DIGEST else bytes(buf)
    pm = _load_or_reject(data)
    if not reseal and data != good:
        assert pm is None  # the checksum catches every change


@HYPO
@given(
    record=st.integers(0, 10**6),
    field=st.sampled_from(["v", "flags", "mask"]),
    value=st.integers(0, 2**64 - 1),
)
@pytest.mark.slow
def test_random_record_contents_with_a_valid_checksum_never_crash_decoding(record, field, value):
    pm = _open_pm()
    r = record % pm.n_records
    v, flags, mask = pm.v.copy(), pm.flags.copy(), pm.mask.copy()
    if field == "v":
        v[r] = value % (pm.n_vertices + 2)
    elif field == "flags":
        flags[r] = value % 4
    else:
        mask[r] = np.uint64(value)
    _load_or_reject(_rebuild(pm, v=v, flags=flags, mask=mask))


@pytest.mark.parametrize("ranks", [(13, 13), (0, 0), (12, 3)])
def test_end_ranks_that_name_the_wrong_faces_never_crash_decoding(ranks):
    """Every record's top bits changed (the checksum resealed): faces past v's degree or not at the
    arc's ends give a wrong mesh, never an index out of range."""
    pm = _open_pm()
    top = np.uint64(0xFFF) << np.uint64(ENDS_SHIFT)
    mask = (pm.mask & ~top) | (np.uint64(ranks[0] | ranks[1] << 6) << np.uint64(ENDS_SHIFT))
    assert _load_or_reject(_rebuild(pm, mask=mask)) is not None


# A version-1 file written by the first encoder and decoder (main at 88eb246): the open icosphere of
# _open_pm. Its decodings (base, a prefix ending inside a level, all) must stay byte-identical to what
# that decoder gave: the SHA-256 of vertices (float64) then faces (int64).
V1_FILE = """
iVBNV00NChoBAAAABgAAAAcAAAAhAAAADwAAAAAAAABAxFk/AAAAAFCWBr9AxFk/AAAAAFCWBj9AxFm/AAAAAFCWBr96N56+
vRtPPwAAAD96N56+vRtPvwAAAL8AAAA/ejeePr0bTz8DAAAABQAAAAAAAAADAAAAAAAAAAIAAAAAAAAABQAAAAEAAAADAAAA
AgAAAAQAAAAEAAAAAgAAAAAAAAAEAAAAAAAAAAEAAAABAAAAAwAAAAQAAAABAAAAAgAAAAMAAAAEAAAABQAAAAcAAAAJAAAA
CwAAAA0AAAAQAAAAEwAAABcAAAAZAAAAHAAAACEAAABQlgY/QMRZvwAAAAAEAAAABgAAAAAAAABQlga/QMRZPwAAAAACAAAA
AQAAAAAAAAB6N54+vRtPPwAAAL8AAAAAJwAAAAAAAAAAAAAAUJYGv0DEWb8CAAAAJgAAAAAAAAC9G0+/AAAAv3o3nj4EAAAA
EwAAAAAAAAC9G08/AAAAv3o3nr4AAAAABQAAAAAAAABAxFm/AAAAAFCWBj8DAABAHAAAAAAAAAC9G0+/AAAAP3o3nr4CAAAA
DAAAAAAAAAB6N56+vRtPvwAAAD8BAADALAAAAAAAAAAAAAA/ejeePr0bT78IAAAA2AAAAAAAAAAAAAA/ejeevr0bTz8BAADA
CAAAAAAAAAB6N54+vRtPvwAAAL8GAAAADQAAAAAAAAB6N56+vRtPPwAAAL8HAAAAJQAAAAAAAAC9G08/AAAAP3o3nr4AAAAA
EgAAAAAAAAAAAAC/ejeevr0bT78JAAAAcAAAAAAAAAAAAAC/ejeePr0bTz8DAABABAAAAAAAAAC9G08/AAAAP3o3nj4BAAAA
FQAAAAAAAAAAAAC/ejeePr0bT78NAAAAKwAAAAAAAAAAAAC/ejeevr0bTz8MAABAAgAAAAAAAAAAAAA/ejeevr0bT78LAAAA
CwAAAAAAAAC9G0+/AAAAv3o3nr4KAAAAFAAAAAAAAAB6N54+vRtPvwAAAD8QAADAAQAAAAAAAAB6N54+vRtPPwAAAD8FAABA
AwAAAAAAAAAAAAAAAACAPwAAAAADAAAABwAAAAAAAAAAAAAAAACAvwAAAAAOAAAAGgAAAAAAAAAAAAAAUJYGP0DEWb8PAAAA
JQAAAAAAAAAAAIA/AAAAAAAAAAAAAAAAMwAAAAAAAAAAAIC/AAAAAAAAAAACAAAASwAAAAAAAABQlgY/QMRZPwAAAAAIAAAA
DQAAAAAAAABQlga/QMRZvwAAAAAEAAAAZAAAAAAAAAAAAAAAAAAAAAAAgL8JAAAAbAAAAAAAAAC9G08/AAAAv3o3nj4GAAAA
SwAAAAAAAAC9G0+/AAAAP3o3nj4HAAAAJwAAAAAAAAAiRtTk3VNbN09t8JioA0/ai5o+Vy3l+vByXjmRx6DbAQ==
"""
V1_DECODED = {
    0: "cc54e033d564dd488c351898dc9d5c4c90c9235045f89df9011f82fd8761b8cd",
    17: "07567eec31ce6740acde07996838431998fc48da293014717a28932e79128afe",
    33: "b69a7e6524f074bac95baf1bca1b5695c20f942e83827fcb2f9f0babe2c44ac3",
}


def test_a_version_1_file_of_the_first_decoder_decodes_as_it_did():
    import base64

    data = base64.b64decode("".join(V1_FILE.split()))
    assert HEADER.unpack_from(data)[1] == 1
    pm = from_bytes(data)
    assert pm.n_records == 33
    for k, digest in V1_DECODED.items():
        V, F = pm.decode(records=k)
        assert hashlib.sha256(V.tobytes() + F.astype(np.int64).tobytes()).hexdigest() == digest, k
    assert to_bytes(pm) == data  # and it is written back byte for byte


# ---------------------------------------------------------------- the key file


@functools.cache
def _key_text() -> str:
    return _cow().key.to_json()


@pytest.fixture(scope="module")
def key_doc() -> dict:
    return json.loads(_key_text())


def test_key_json_round_trip_is_exact(cow):
    back = load_key_data(WatermarkKey.from_json(cow.key.to_json()))
    for f in dataclasses.fields(WatermarkKey):
        a, b = getattr(cow.key, f.name), getattr(back, f.name)
        if f.name == "data":  # the scheme's typed data: equal when their stored forms are
            assert json.dumps(a.to_extra()) == json.dumps(b.to_extra())
        elif f.name == "extra":  # as read from the file: the stored form of that data
            assert b == json.loads(json.dumps(cow.key.data.to_extra()))
        elif isinstance(a, np.ndarray):
            assert a.shape == b.shape and np.array_equal(a, b), f.name
        else:
            assert a == b, f.name


@pytest.mark.parametrize(
    "text",
    [
        "",
        "not json",
        "[" * 100_000,  # deeply nested: the parser must not blow the stack into a RecursionError
        "null",
        "[]",
        '{"format": "pmwm-key"}',
        '{"format": "pmwm-key", "version": 2}',
        '{"format": "pmwm-key", "version": "1"}',
    ],
    ids=["empty", "text", "deep", "null", "list", "no-version", "future", "version-string"],
)
def test_malformed_key_text_gives_keyfileerror(text):
    with pytest.raises(KeyFileError):
        WatermarkKey.from_json(text)


@pytest.mark.parametrize(
    "path,value",
    [
        (("mesh", "n_vertices"), "1e400"),  # parses as float infinity
        (("mesh", "n_faces"), "-1e400"),
        (("mesh", "n_vertices"), "NaN"),
        (("mesh", "mean_edge"), "Infinity"),
        (("strength",), "[]"),
        (("bits",), "12"),
        (("carriers",), '"x"'),
        (("secret",), "null"),
        (("extra",), '"abc"'),
    ],
)
def test_key_fields_of_the_wrong_kind_give_keyfileerror(key_doc, path, value):
    doc = json.loads(json.dumps(key_doc))
    target = doc
    for p in path[:-1]:
        target = target[p]
    target[path[-1]] = "@@VALUE@@"
    text = json.dumps(doc).replace('"@@VALUE@@"', value)
    with pytest.raises(KeyFileError):
        WatermarkKey.from_json(text)


@pytest.mark.parametrize(
    "index,pm_index",
    [(-1_000_000_000, -1_000_000_000), (-3, 5), (10**12, 10**12), (1e30, -1e30), (0.5, 2.5)],
)
def test_a_key_with_impossible_carrier_indices_is_refused_or_verifies_cleanly(cow, key_doc, index, pm_index):
    """Carrier indices point into the marked mesh: one that cannot (negative, huge, fractional)
    must give KeyFileError when read, or be treated as a carrier not found; never a crash."""
    doc = json.loads(json.dumps(key_doc))
    doc["carriers"][0][0] = index
    doc["carriers"][0][1] = pm_index
    try:
        key = load_key_data(WatermarkKey.from_json(json.dumps(doc)))
    except KeyFileError:
        return
    verdict = pmwm.verify(cow.vertices, cow.faces, key)
    assert verdict.carriers_total == len(doc["carriers"])


def _paths(doc) -> tuple[list, list]:
    """Every place a value sits in the key document: (non-carrier paths, carrier paths)."""
    top, car = [], []

    def walk(node, path):
        (car if path and path[0] == "carriers" else top).append(path)
        if isinstance(node, dict):
            for k, v in node.items():
                walk(v, path + (k,))
        elif isinstance(node, list):
            for i, v in enumerate(node):
                walk(v, path + (i,))

    for k, v in doc.items():
        walk(v, (k,))
    return top, car


_json_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(2**70), 2**70)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=6),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=4), inner, max_size=3),
    max_leaves=6,
)


@HYPO
@given(data=st.data())
@pytest.mark.slow
def test_mutated_key_documents_give_keyfileerror_or_a_key_that_verifies_cleanly(data):
    cow = _cow()
    key_doc = json.loads(_key_text())
    top, car = _paths(key_doc)
    path = data.draw(st.sampled_from(top) | st.sampled_from(car), label="path")
    doc = json.loads(json.dumps(key_doc))
    parent = doc
    for p in path[:-1]:
        parent = parent[p]
    if data.draw(st.booleans(), label="delete"):
        del parent[path[-1]]
    else:
        parent[path[-1]] = data.draw(_json_values, label="value")
    try:
        key = load_key_data(WatermarkKey.from_json(json.dumps(doc)))
    except KeyFileError:
        return
    try:  # an accepted key must be usable: a verdict, or a clean pmwm error
        pmwm.verify(cow.vertices, cow.faces, key)
    except PmwmError:
        pass


_text_edit = st.tuples(
    st.sampled_from(["set", "insert", "delete"]),
    st.integers(0, 1 << 20),
    st.sampled_from(list('{}[]",:-+.eE0123456789 ntfalsrueINaN\\\x00\u00e9')) | st.characters(),
)


@HYPO
@given(edits=st.lists(_text_edit, min_size=1, max_size=6))
@pytest.mark.slow
def test_mutated_key_text_gives_keyfileerror_or_a_key(edits):
    buf = list(_key_text())
    for op, pos, ch in edits:
        i = pos % (len(buf) + 1)
        if op == "insert":
            buf.insert(i, ch)
        elif buf and op == "set":
            buf[i % len(buf)] = ch
        elif buf:
            del buf[i % len(buf)]
    try:
        key = load_key_data(WatermarkKey.from_json("".join(buf)))
    except KeyFileError:
        return
    assert isinstance(key, WatermarkKey)
