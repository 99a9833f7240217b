"""The record lengths of an MCAP file checked before a reader trusts them (bags layer).

An MCAP file is a sequence of records, each an opcode byte, a ``uint64`` length and that many
bytes (MCAP specification, "Records"). ``rosbags``' reader reads a record by asking the file
for its declared length at once, so a corrupt or truncated file whose length field reads
2^62 ends in a ``MemoryError`` (or a multi-gigabyte allocation) before any check.
:func:`check_mcap` walks the file's records first, reading only their headers (a memory map,
no record is copied), and refuses in one line, naming the file, the record's byte offset and
what is wrong, any record that declares more bytes than the file has left, and any chunk
whose compressed or uncompressed size does not fit its record or :data:`MAX_CHUNK_BYTES`.

Checked: every top-level record (the data section and the summary); inside a ``Chunk``
(opcode 0x06) its compression name, its records' byte count and its uncompressed size; a
``ChunkIndex`` (0x08), which the reader follows to a chunk, its offset, length and sizes
against the file; a ``Statistics`` record's (0x0B) channel counts. The records inside a chunk
are read by the reader from memory, where a bad length is a short read it reports itself.
"""

from __future__ import annotations

import mmap
import struct
from pathlib import Path

from ..errors import InvalidInputError

__all__ = ["MAGIC", "MAX_CHUNK_BYTES", "check_mcap"]

#: The 8 bytes an MCAP file starts and ends with.
MAGIC = b"\x89MCAP0\r\n"
#: Largest uncompressed chunk accepted (4 GiB): a reader decompresses one chunk at a time into
#: memory; ROS 2 recorders write chunks of a few MiB.
MAX_CHUNK_BYTES = 1 << 32

_OP_FOOTER, _OP_CHUNK, _OP_CHUNK_INDEX, _OP_STATISTICS = 0x02, 0x06, 0x08, 0x0B
_U32, _U64 = struct.Struct("<I"), struct.Struct("<Q")


def _bytes(n: int) -> str:
    """``n`` bytes, with its power of two when it is one above 1 MiB (``2^62``)."""
    return f"{n} bytes" + (f" (2^{n.bit_length() - 1})" if n >= 1 << 20 and n & (n - 1) == 0 else "")


class _Record:
    """Reads the fields of one record's content ``[start, end)`` of ``data``, refusing overruns."""

    def __init__(self, check, data, offset: int, opcode: int, start: int, end: int):
        self.check, self.data, self.offset, self.opcode = check, data, offset, opcode
        self.pos, self.end = start, end

    def fail(self, what: str):
        self.check.fail(f"record at byte {self.offset} (opcode 0x{self.opcode:02x}) {what}")

    def need(self, n: int, what: str) -> None:
        if n > self.end - self.pos:
            self.fail(f"declares {what} of {_bytes(n)}, the record has {self.end - self.pos} left")

    def u32(self, what: str) -> int:
        self.need(4, what)
        (v,) = _U32.unpack_from(self.data, self.pos)
        self.pos += 4
        return v

    def u64(self, what: str) -> int:
        self.need(8, what)
        (v,) = _U64.unpack_from(self.data, self.pos)
        self.pos += 8
        return v

    def skip(self, n: int, what: str) -> None:
        self.need(n, what)
        self.pos += n

    def string(self, what: str) -> str:
        n = self.u32(f"{what}'s length")
        self.need(n, what)
        s = bytes(self.data[self.pos:self.pos + n]).decode("utf-8", "replace")
        self.pos += n
        return s


class _Check:
    def __init__(self, path, size: int):
        self.path, self.size = path, size

    def fail(self, what: str):
        raise InvalidInputError(f"bag {self.path} is truncated or corrupt: {what}; copy or record the file again")


def check_mcap(path) -> None:
    """Refuse, in one line, an MCAP file ``path`` whose records declare more bytes than it holds.

    A file that does not start with the MCAP magic, or is shorter than it, is left to the
    reader (which says so). See the module docstring for what is checked.

    Raises
    ------
    InvalidInputError
        ``bag <path> is truncated or corrupt: record at byte N (opcode 0x..) declares M bytes,
        the file has K left; ...``.
    """
    path = Path(path)
    size = path.stat().st_size
    if size < len(MAGIC) + 9:
        return
    with open(path, "rb") as f:
        if f.read(len(MAGIC)) != MAGIC:
            return
        with mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as data:
            _walk(_Check(path, size), data, size)


def _walk(check: _Check, data, size: int) -> None:
    end = size - len(MAGIC) if data[size - len(MAGIC):size] == MAGIC else size
    pos = len(MAGIC)
    while pos < end:
        if end - pos < 9:
            check.fail(f"the record at byte {pos} has {end - pos} of its 9 header bytes")
        opcode = data[pos]
        (n,) = _U64.unpack_from(data, pos + 1)
        left = end - (pos + 9)
        if n > left:
            check.fail(f"record at byte {pos} (opcode 0x{opcode:02x}) declares {_bytes(n)}, the file has {left} left")
        rec = _Record(check, data, pos, opcode, pos + 9, pos + 9 + n)
        if opcode == _OP_CHUNK:
            _chunk(rec)
        elif opcode == _OP_CHUNK_INDEX:
            _chunk_index(rec, end)
        elif opcode == _OP_STATISTICS:
            rec.skip(42, "its counts")
            rec.skip(rec.u32("its channel counts' length"), "channel counts")
        pos += 9 + n
        if opcode == _OP_FOOTER:
            break


def _uncompressed(rec: _Record, compression: str, compressed: int, uncompressed: int) -> None:
    if uncompressed > MAX_CHUNK_BYTES:
        rec.fail(f"declares an uncompressed chunk of {_bytes(uncompressed)}, more than the "
                 f"{_bytes(MAX_CHUNK_BYTES)} a chunk may hold")
    if not compression and uncompressed != compressed:
        rec.fail(f"declares an uncompressed chunk of {_bytes(uncompressed)} holding {_bytes(compressed)}")


def _chunk(rec: _Record) -> None:
    """Chunk: start, end time (u64), uncompressed size (u64), CRC (u32), compression, records (u64 + bytes)."""
    rec.skip(16, "its times")
    uncompressed = rec.u64("its uncompressed size")
    rec.skip(4, "its CRC")
    compression = rec.string("its compression name")
    compressed = rec.u64("its records' length")
    rec.need(compressed, "records")
    _uncompressed(rec, compression, compressed, uncompressed)


def _chunk_index(rec: _Record, end: int) -> None:
    """ChunkIndex: times (2 u64), chunk start, chunk length (u64), message index offsets (u32 +
    bytes), message index length (u64), compression, compressed and uncompressed sizes (u64)."""
    rec.skip(16, "its times")
    start, length = rec.u64("its chunk's offset"), rec.u64("its chunk's length")
    rec.skip(rec.u32("its message index offsets' length"), "message index offsets")
    rec.skip(8, "its message index length")
    compression = rec.string("its compression name")
    compressed, uncompressed = rec.u64("its compressed size"), rec.u64("its uncompressed size")
    if start > end or length > end - start:
        left = max(0, end - start)
        rec.fail(f"points at a chunk of {_bytes(length)} at byte {start}, the file has {left} left there")
    if compressed > length:
        rec.fail(f"declares a compressed chunk of {_bytes(compressed)} in a chunk record of {_bytes(length)}")
    _uncompressed(rec, compression, compressed, uncompressed)
