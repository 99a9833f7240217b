"""Many messages of one shape serialised at once: CDR offsets of a template's fields (bags layer).

A topic of a run carries one message per logged sample, and every message of a topic has the
same shape (the same frame names, the same number of points, joints, transforms): only its
numbers change. So its CDR bytes have one layout. :func:`field_offsets` walks a template
message in the order the CDR serialiser writes it (OMG DDS-XTypes 1.3 §7.4.3, XCDR1 little
endian as ROS 2 writes it: a 4-byte encapsulation header, then each primitive aligned to its
size counted from the end of that header; a string is a 4-aligned ``uint32`` length with its
terminating NUL, then its bytes; a sequence a 4-aligned ``uint32`` count, then its elements)
and returns where every number lies. :class:`Batch` then writes ``T`` messages as one
``(T, nbytes)`` byte array: the template's bytes repeated, each varying field written as a
column. The template itself is serialised by ``rosbags`` (the layout is checked against its
length), and the tests compare the batch with ``rosbags``' serialiser message by message.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError, ShapeError

__all__ = ["field_offsets", "Batch"]

#: Bytes and NumPy type of the CDR primitives.
_PRIMITIVES = {
    "bool": (1, "<u1"), "byte": (1, "<u1"), "char": (1, "<u1"), "int8": (1, "<i1"), "uint8": (1, "<u1"),
    "int16": (2, "<i2"), "uint16": (2, "<u2"), "int32": (4, "<i4"), "uint32": (4, "<u4"),
    "int64": (8, "<i8"), "uint64": (8, "<u8"), "float32": (4, "<f4"), "float64": (8, "<f8"),
}
_ENCAPSULATION = 4  # bytes of the CDR header before the body; alignment counts from its end


def _align(pos: int, size: int) -> int:
    body = pos - _ENCAPSULATION
    return pos + (-body) % size


def field_offsets(store, msg, typename: str | None = None) -> tuple[dict, int]:
    """Byte offsets of every numeric field of ``msg`` in its CDR serialisation.

    Parameters
    ----------
    store : rosbags Typestore
        The type store holding ``msg``'s definition.
    msg : rosbags message
    typename : str, optional
        Its type (default ``msg.__msgtype__``).

    Returns
    -------
    offsets : dict
        ``{path: (offset, numpy dtype)}``; a path is the tuple of field names and sequence
        indices (``("transforms", 1, "transform", "translation", "x")``).
    nbytes : int
        The serialised length.
    """
    from rosbags.interfaces import Nodetype

    out: dict = {}

    def base(value, kind: str, pos: int, path: tuple) -> int:
        if kind == "string":
            pos = _align(pos, 4)
            return pos + 4 + len(str(value).encode()) + 1
        size, dtype = _PRIMITIVES[kind]
        pos = _align(pos, size)
        out[path] = (pos, dtype)
        return pos + size

    def node(value, nodetype, desc, pos: int, path: tuple) -> int:
        if nodetype == Nodetype.BASE:
            return base(value, desc[0], pos, path)
        if nodetype == Nodetype.NAME:
            return struct(value, desc, pos, path)
        (sub_type, sub_desc), _ = desc
        if nodetype == Nodetype.SEQUENCE:
            pos = _align(pos, 4) + 4
        for j, item in enumerate(value):
            pos = node(item, sub_type, sub_desc, pos, path + (j,))
        return pos

    def struct(value, name: str, pos: int, path: tuple) -> int:
        fields = store.fielddefs[name][1]
        if not fields:  # an empty struct is one uint8 (ROS 2's structure_needs_at_least_one_member)
            return pos + 1
        for fname, (nodetype, desc) in fields:
            pos = node(getattr(value, fname), nodetype, desc, pos, path + (fname,))
        return pos

    nbytes = struct(msg, typename or msg.__msgtype__, _ENCAPSULATION, ())
    return out, nbytes


@dataclass(frozen=True)
class Batch:
    """``T`` messages of one template's shape, as CDR bytes.

    Attributes
    ----------
    msgtype : str
        ``geometry_msgs/msg/PoseStamped`` ...
    data : ndarray of uint8, shape (T, nbytes)
        Message ``k`` is ``data[k]``.
    """

    msgtype: str
    data: np.ndarray

    @classmethod
    def build(cls, store, template, columns: dict, n: int) -> Batch:
        """``n`` copies of ``template`` with the fields of ``columns`` (``{path: (n,) values}``) set.

        The layout is the template's: every message keeps its strings and sequence lengths.
        """
        raw = np.frombuffer(bytes(store.serialize_cdr(template, template.__msgtype__)), dtype=np.uint8)
        offsets, nbytes = field_offsets(store, template)
        if nbytes != raw.size:  # pragma: no cover - the walk mirrors rosbags' serialiser
            raise ShapeError(f"CDR layout of {template.__msgtype__}: walked {nbytes} bytes, rosbags wrote {raw.size}")
        data = np.tile(raw, (n, 1))
        groups: dict = {}
        for path, values in columns.items():
            if path not in offsets:
                raise InvalidInputError(f"{template.__msgtype__} has no numeric field {'.'.join(map(str, path))}")
            col = np.asarray(values)
            if col.shape != (n,):
                raise ShapeError(f"{template.__msgtype__}.{'.'.join(map(str, path))}: {col.shape} values for {n} "
                                 "messages")
            off, dtype = offsets[path]
            groups.setdefault(dtype, ([], []))
            groups[dtype][0].append(off)
            groups[dtype][1].append(col)
        for dtype, (offs, cols) in groups.items():  # one scatter per primitive type, every field at once
            size = np.dtype(dtype).itemsize
            idx = np.asarray(offs, dtype=np.intp)[:, None] + np.arange(size)
            values = np.ascontiguousarray(np.stack(cols, axis=1).astype(dtype))  # (n, fields)
            data[:, idx] = values.view(np.uint8).reshape(n, len(offs), size)
        return cls(template.__msgtype__, data)

    @staticmethod
    def read(store, template, raw: np.ndarray, paths) -> dict:
        """The fields ``paths`` of messages of ``template``'s layout, from their bytes ``raw`` (T, nbytes)."""
        offsets, nbytes = field_offsets(store, template)
        if raw.ndim != 2 or raw.shape[1] != nbytes:
            raise ShapeError(f"{template.__msgtype__}: messages of {raw.shape[1:]} bytes for a layout of {nbytes}")
        paths = list(paths)
        out = {}
        by_type: dict = {}
        for path in paths:
            off, dtype = offsets[path]
            by_type.setdefault(dtype, []).append((path, off))
        for dtype, items in by_type.items():  # one gather per primitive type
            size = np.dtype(dtype).itemsize
            idx = np.asarray([off for _, off in items], dtype=np.intp)[:, None] + np.arange(size)
            values = np.ascontiguousarray(raw[:, idx]).view(dtype)[..., 0]  # (T, fields)
            for j, (path, _) in enumerate(items):
                out[path] = values[:, j]
        return {path: out[path] for path in paths}
