"""Text logs parsed a block of bytes at a time by pyarrow's CSV parser (vectorised).

The fast path of :func:`ident.measure.readers.csv_long.read_csv_long`: the text (decompressed
on the fly) is read :data:`BLOCK_BYTES` at a time, each block cut after its last line break,
and parsed at once; pyarrow runs at about 0.3 us per row where splitting lines in Python
took about 10 us. Memory: a block's bytes, its parsed columns and the carried partial line.

Only text that the line-by-line reader reads the same way is accepted here: anything else
(a missing value, a field that is not a number, a quoted field, a line with another number of
fields, a whitespace-only line, a line longer than
:data:`~ident.measure.readers.csv.MAX_LINE_CHARS` bytes, undecodable text) raises
:class:`NotPlain`, and the caller reads the file line by line, whose errors name the line.
Imported when a long log is read (pyarrow takes 0.15 s to import).
"""

from __future__ import annotations

import io
import zlib
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pa_csv

from ident.measure.readers.csv import MAX_LINE_CHARS, open_bytes

__all__ = ["BLOCK_BYTES", "NotPlain", "number_blocks"]

BLOCK_BYTES = 1 << 22  # text parsed at once (4 MiB: about 85 000 rows of a 7-joint log)

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


class NotPlain(Exception):
    """The text is not plain delimited numbers (and one text field): read it line by line."""


def _cut(f: io.BufferedIOBase, block_bytes: int) -> Iterator[bytes | memoryview]:
    """The text after its first line (the header), in blocks of whole lines of about
    ``block_bytes`` (the last one may lack its line break); NotPlain for a line longer than
    :data:`MAX_LINE_CHARS` bytes (a character is at least a byte)."""
    rest, header = b"", True
    while data := f.read(block_bytes):
        data = rest + data
        if header:  # drop line 1, the header
            start = data.find(b"\n") + 1
            if not start:
                rest = data
                if len(rest) > MAX_LINE_CHARS:
                    raise NotPlain
                continue
            data, header = data[start:], False
        cut = data.rfind(b"\n") + 1
        block, rest = memoryview(data)[:cut], data[cut:]  # the block not copied
        if len(rest) > MAX_LINE_CHARS:
            raise NotPlain
        if block:
            _check_lengths(block)
            yield block
    if rest and not header:
        _check_lengths(rest + b"\n")
        yield rest


def _check_lengths(block: bytes | memoryview) -> None:
    """NotPlain when a line of ``block`` (whole lines) is longer than MAX_LINE_CHARS bytes."""
    breaks = np.flatnonzero(np.frombuffer(block, dtype=np.uint8) == ord("\n"))
    if breaks.size and np.diff(breaks, prepend=-1).max() > MAX_LINE_CHARS:
        raise NotPlain


def _parse(
    block: bytes | memoryview, delimiter: str, n_fields: int, text_field: int
) -> tuple[list[str], IntArray, FloatArray]:
    """The distinct texts of field ``text_field`` in order of first appearance (m,) row
    indices into them, and the numbers (m, n_fields - 1) of the other fields of ``block``."""
    # malloc, whose freed blocks the identification reuses (pyarrow's own pool kept ~40 MB of
    # them resident through the rest of the run): for the parse and the joint column's codes
    pool = pa.system_memory_pool()
    names = [f"c{k}" for k in range(n_fields)]
    types = {name: pa.float64() for name in names}
    types[names[text_field]] = pa.string()
    table = pa_csv.read_csv(
        pa.BufferReader(pa.py_buffer(block)),
        read_options=pa_csv.ReadOptions(
            column_names=names, use_threads=False, block_size=len(block) + 1
        ),
        parse_options=pa_csv.ParseOptions(delimiter=delimiter, quote_char=False),
        memory_pool=pool,
        convert_options=pa_csv.ConvertOptions(
            column_types=types, null_values=[], strings_can_be_null=False
        ),
    )
    numbers = np.empty((table.num_rows, n_fields - 1))
    for j, k in enumerate(k for k in range(n_fields) if k != text_field):
        numbers[:, j] = table.column(k).to_numpy()
    encoded = pc.dictionary_encode(table.column(text_field), memory_pool=pool).combine_chunks(
        memory_pool=pool
    )
    index = encoded.indices.to_numpy().astype(np.int64)
    texts = encoded.dictionary.to_pylist()
    # the dictionary holds the texts in order of first appearance (a hash table filled row
    # by row): each row's index is at most one more than all before it (else line by line)
    reached = np.maximum.accumulate(index)
    if index.size and (index[0] != 0 or np.any(index[1:] > reached[:-1] + 1)):
        raise NotPlain
    return texts, index, numbers


def number_blocks(
    path: Path, delimiter: str, n_fields: int, text_field: int, block_bytes: int = BLOCK_BYTES
) -> Iterator[tuple[list[str], IntArray, FloatArray]]:
    """Per block of ``path`` after its header line (``n_fields`` fields a line, separated by
    the one character ``delimiter``): the texts of field ``text_field`` in order of first
    appearance, each row's index into them (m,), and the numbers of the other fields
    (m, n_fields - 1), in the file's order.

    Raises
    ------
    NotPlain
        For text the line-by-line reader may read otherwise or refuse (see the module).
    """
    if len(delimiter) != 1 or delimiter in '\r\n"':
        raise NotPlain
    try:
        with open_bytes(path) as f:
            for block in _cut(f, block_bytes):
                texts, index, numbers = _parse(block, delimiter, n_fields, text_field)
                if numbers.shape[0]:
                    yield texts, index, numbers
    except (pa.ArrowException, OSError, EOFError, ValueError, zlib.error) as e:
        raise NotPlain from e
