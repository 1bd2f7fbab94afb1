"""Parquet files written with page checksums (the run-directory store audit): a bit flipped
inside a data page leaves a file's size and footer intact, and was read as changed numbers;
files written before the checksums read as they did."""

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from railsusp.errors import RailsuspInputError
from railsusp.store import parquet_readable, read_parquet, write_parquet


def _table() -> pd.DataFrame:
    rng = np.random.default_rng(0)
    return pd.DataFrame({"sample_id": np.arange(500), "Q": rng.normal(120.0, 5.0, 500)})


def flip_a_bit_in_a_page(path) -> None:
    """One bit flipped in the middle of the last column's pages of a Parquet file: its size
    and footer stay as they were (what a failing disk or a bad copy can do). Used by the
    tests of every reader that verifies the checksums."""
    size = path.stat().st_size
    meta = pq.ParquetFile(path).metadata
    column = meta.row_group(0).column(meta.num_columns - 1)
    start = column.dictionary_page_offset or column.data_page_offset
    data = bytearray(path.read_bytes())
    data[start + column.total_compressed_size // 2] ^= 0x01
    path.write_bytes(bytes(data))
    assert path.stat().st_size == size
    assert pq.ParquetFile(path).metadata.num_rows > 0  # the footer still reads


def test_a_bit_flipped_in_a_page_is_found_by_its_checksum(tmp_path):
    path = write_parquet(tmp_path / "t.parquet", _table())
    size = path.stat().st_size
    flip_a_bit_in_a_page(path)
    assert path.stat().st_size == size and parquet_readable(path)  # the footer reads
    with pytest.raises(OSError, match="CRC checksum verification failed"):
        pq.read_table(path, page_checksum_verification=True)  # written with checksums
    assert not parquet_readable(path, pages=True)
    with pytest.raises(RailsuspInputError) as info:
        read_parquet(path, "make it again")
    text = str(info.value)
    assert text.startswith(f"{path} is damaged (") and text.endswith("; make it again")
    assert "\n" not in text


def test_a_file_written_without_checksums_reads_as_before(tmp_path):
    path = tmp_path / "old.parquet"
    pq.write_table(pq.read_table(write_parquet(tmp_path / "t.parquet", _table())), path)
    assert parquet_readable(path, pages=True)
    pd.testing.assert_frame_equal(read_parquet(path), _table())
    with pytest.raises(RailsuspInputError, match=r"gone.parquet does not exist; again$"):
        read_parquet(tmp_path / "gone.parquet", "again")
