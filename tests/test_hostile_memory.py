"""Small files that would take gigabytes: refused in one error line, in bounded memory.

The bombs are built in well under a second: a deflate stream of zeros is made of one
compressed block repeated (each ends with a full flush, so it is byte-aligned and does not
refer to the ones before), wrapped in a zip member or a gzip file by hand. Their CRCs are
wrong, as a forger's may be: a reader only finds out once it has decompressed everything.

``ident logs inspect`` runs in a child process with ``IDENT_MAX_MEMORY_GB`` unset; the child
prints its own peak resident memory (``VmHWM``) and the parent kills it if its resident
memory passes :data:`KILL_BYTES` (the readers before this bound allocated gigabytes: 3.3 GB
for the archive, and read the text for minutes).
"""

from __future__ import annotations

import gzip
import os
import struct
import subprocess
import sys
import time
import zlib
from pathlib import Path

import numpy as np
import pytest

from ident import inputs
from ident.errors import ConfigError
from ident.inputs import JobEstimate, ResourceLimitError, check_job, resource_ceilings

ROOT = Path(__file__).resolve().parents[1]
PEAK_BYTES = 500e6  # the child's peak: the interpreter and ident's libraries, ~0.3 GB
KILL_BYTES = 1.2e9  # resident memory at which the parent stops a child that runs away
TIMEOUT_S = 120.0


def _deflated_zeros(prefix: bytes, unit: bytes, repeats: int) -> bytes:
    """A raw deflate stream of ``prefix`` then ``unit`` ``repeats`` times, built from one
    compressed block of ``unit``."""
    c = zlib.compressobj(9, zlib.DEFLATED, -15)
    head = c.compress(prefix) + c.flush(zlib.Z_FULL_FLUSH)
    block = c.compress(unit) + c.flush(zlib.Z_FULL_FLUSH)
    return head + block * repeats + c.flush(zlib.Z_FINISH)


def _npz_bomb(path: Path, n: int = 100_000_000) -> Path:
    """A ``.npz`` of ``t`` (n,) and ``q`` (n, 5) zeros (4.8 GB declared, 4.7 MB on disk)."""
    local, central = bytearray(), bytearray()
    for name, shape in (("t.npy", (n,)), ("q.npy", (n, 5))):
        header = {"descr": "<f8", "fortran_order": False, "shape": shape}
        text = repr(header).encode()
        text += b" " * (63 - (10 + len(text)) % 64) + b"\n"
        npy = b"\x93NUMPY\x01\x00" + struct.pack("<H", len(text)) + text
        size = len(npy) + 8 * int(np.prod(shape))
        unit = bytes(4_000_000)
        data = _deflated_zeros(npy, unit, (size - len(npy)) // len(unit))
        fields = struct.pack("<HHHHHIII", 20, 0, 8, 0, 0, 0, len(data), size)
        fields += struct.pack("<HH", len(name), 0)
        central += b"PK\x01\x02" + struct.pack("<H", 20) + fields
        central += struct.pack("<HHHII", 0, 0, 0, 0, len(local)) + name.encode()
        local += b"PK\x03\x04" + fields + name.encode() + data
    end = struct.pack("<4sHHHHIIH", b"PK\x05\x06", 0, 0, 2, 2, len(central), len(local), 0)
    path.write_bytes(bytes(local + central + end))
    return path


def _csv_bomb(path: Path) -> Path:
    """A ``.csv.gz`` of 5.6 GB of constant rows (11 MB on disk) whose trailer says 1 MB."""
    line = b"0,0,0,0,0,0,0,0\n"
    body = _deflated_zeros(b"t,q1,q2,q3,tau1,tau2,tau3,x\n", line * 250_000, 1400)
    gz_header = b"\x1f\x8b\x08\x00\x00\x00\x00\x00\x00\xff"
    path.write_bytes(gz_header + body + struct.pack("<II", 0, 1 << 20))
    return path


_CHILD = """
import sys
from ident.cli import main
def peak():
    with open("/proc/self/status") as f:
        return next(int(x.split()[1]) for x in f if x.startswith("VmHWM:")) * 1024
try:
    sys.argv = ["ident", *sys.argv[1:]]
    main()
finally:
    print(f"peak {peak()}", file=sys.stderr)
"""


def _rss(pid: int) -> int:
    try:
        with open(f"/proc/{pid}/status") as f:
            return next((int(x.split()[1]) * 1024 for x in f if x.startswith("VmRSS:")), 0)
    except OSError:
        return 0


def _inspect(path: Path) -> tuple[int, list[str], float]:
    """Exit code, stderr lines (without the peak) and peak memory [bytes] of ``ident logs
    inspect path`` in a child without ``IDENT_MAX_MEMORY_GB``, stopped above KILL_BYTES."""
    env = {k: v for k, v in os.environ.items() if k != "IDENT_MAX_MEMORY_GB"}
    env["PYTHONPATH"] = str(ROOT / "src")
    args = [sys.executable, "-c", _CHILD, "logs", "inspect", str(path)]
    child = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    start, highest = time.monotonic(), 0
    while child.poll() is None:
        highest = max(highest, _rss(child.pid))
        if highest > KILL_BYTES or time.monotonic() - start > TIMEOUT_S:
            child.kill()
            child.wait()
            pytest.fail(f"ident logs inspect {path.name}: {highest / 1e9:.2f} GB resident, stopped")
        time.sleep(0.05)
    lines = child.stderr.read().decode().splitlines()
    peak = float(next(x.split()[1] for x in lines if x.startswith("peak ")))
    return child.returncode, [x for x in lines if not x.startswith("peak ")], peak


@pytest.mark.parametrize("make", [_npz_bomb, _csv_bomb], ids=["npz", "csv.gz"])
def test_bombs_end_in_one_error_line_in_bounded_memory(tmp_path, make):
    path = make(tmp_path / ("bomb.npz" if make is _npz_bomb else "bomb.csv.gz"))
    assert path.stat().st_size < 12e6
    code, lines, peak = _inspect(path)
    assert code == 2, lines
    assert len(lines) == 1, lines
    assert lines[0].startswith("error: ")
    assert path.name in lines[0]
    print(f"{path.name}: {lines[0]} peak {peak / 1e6:.0f} MB")
    assert "IDENT_MAX_MEMORY_GB" in lines[0]
    assert peak < PEAK_BYTES, peak


def test_default_memory_ceiling_is_a_quarter_of_the_memory_at_most_4_gb(monkeypatch):
    monkeypatch.delenv("IDENT_MAX_MEMORY_GB", raising=False)
    for physical, ceiling in [(8e9, 2e9), (16e9, 4e9), (64e9, 4e9), (2e9, 0.5e9)]:
        monkeypatch.setattr(inputs, "_physical_memory", lambda p=physical: p)
        assert resource_ceilings()[0] == pytest.approx(ceiling)
    with pytest.raises(ResourceLimitError, match=r"ceiling of 500 MB \(the default.*IDENT_MAX"):
        check_job(JobEstimate("job", 0.6e9, 1.0))
    monkeypatch.setenv("IDENT_MAX_MEMORY_GB", "0.7")  # the variable wins over the default
    assert check_job(JobEstimate("job", 0.6e9, 1.0)).memory_bytes == 0.6e9


def _compressed_bag(path: Path) -> Path:
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    writer = Writer(path, version=9)
    writer.set_compression(CompressionMode.FILE, CompressionFormat.ZSTD)
    with writer:
        conn = writer.add_connection("/cmd", "std_msgs/msg/Float64MultiArray", typestore=store)
        Array = store.types["std_msgs/msg/Float64MultiArray"]
        Layout = store.types["std_msgs/msg/MultiArrayLayout"]
        for k in range(50):
            msg = Array(layout=Layout(dim=[], data_offset=0), data=np.arange(3.0) + k)
            writer.write(conn, 1000 + k, store.serialize_cdr(msg, conn.msgtype))
    return path


def test_whole_file_compressed_bag_is_decompressed_with_a_bound(tmp_path, monkeypatch):
    import zstandard

    from ident.measure.readers import read_tables

    bag = _compressed_bag(tmp_path / "bag")
    (table,) = read_tables(bag)
    np.testing.assert_array_equal(table.columns["/cmd/data/2"], np.arange(50) + 2.0)
    (storage,) = bag.glob("*.zstd")
    monkeypatch.setenv("IDENT_MAX_MEMORY_GB", "0.01")  # 10 MB
    # a frame that declares 20 MB: refused before a byte is decompressed
    storage.write_bytes(zstandard.ZstdCompressor().compress(bytes(20_000_000)))
    with pytest.raises(ConfigError, match=r"bag.db3.zstd: declares 20000000 bytes.*IDENT_MAX"):
        read_tables(bag)
    # one that declares nothing: refused once 10 MB are decompressed, not at its 200 MB end
    with open(storage, "wb") as f, zstandard.ZstdCompressor().stream_writer(f) as w:
        for _ in range(100):
            w.write(bytes(2_000_000))
    with pytest.raises(ConfigError, match=r"bag.db3.zstd: holds more than 10\d{6} bytes"):
        read_tables(bag)


def test_csv_bomb_helper_is_what_it_says(tmp_path):
    """The hand-made gzip and zip streams decompress to what they declare (first bytes)."""
    with gzip.open(_csv_bomb(tmp_path / "b.csv.gz"), "rb") as f:
        assert f.read(60) == b"t,q1,q2,q3,tau1,tau2,tau3,x\n" + b"0,0,0,0,0,0,0,0\n" * 2
    from ident.measure.readers import estimate_read

    estimate = estimate_read(_npz_bomb(tmp_path / "b.npz"))
    assert estimate is not None
    assert estimate.memory_bytes == pytest.approx(8 * 6e8, rel=1e-3)
