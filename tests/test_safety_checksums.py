"""Parquet read with its pages' checksums verified where validate and the perturbed twins
read it: a bit flipped in a data page leaves the footer and the size intact, and
``pd.read_parquet`` read it as other numbers (other Sobol indices for the Sobol flag, other
moves for the twins). Each test failed on the code before (read without a word)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from railsusp.campaign.design import CampaignError
from railsusp.errors import RailsuspInputError
from railsusp.identification_verdict import max_st
from railsusp.store import write_parquet
from test_safety_stamp import make_run
from test_store_checksums import flip_a_bit_in_a_page


def test_max_st_refuses_damaged_indices(tmp_path):
    """A bit flipped in ``indices.parquet``'s ST pages was read as other indices."""
    run = make_run(tmp_path / "run", "now")
    path = run / "campaign" / "sensitivity" / "indices.parquet"
    flip_a_bit_in_a_page(path)
    with pytest.raises(RailsuspInputError) as info:
        max_st(path)
    text = str(info.value)
    assert text.startswith(f"{path} is damaged (") and "\n" not in text
    assert text.endswith(f"; run `railsusp sensitivity {run / 'campaign'}` again")


def test_damaged_perturbations_are_refused(tmp_path):
    """A bit flipped in the perturbed twins' table of moves was read as other moves."""
    from railsusp.campaign.perturbed import perturbed_folder, read_perturbations

    n = 400
    table = pd.DataFrame(
        {
            "sample_id": np.arange(n, dtype=np.int64),
            "twin": np.zeros(n, dtype=np.int64),
            "parameter": ["X13"] * n,
            "delta_unit": np.linspace(-0.05, 0.05, n),
        }
    )
    path = write_parquet(perturbed_folder(tmp_path) / "perturbations.parquet", table)
    pd.testing.assert_frame_equal(read_perturbations(tmp_path), table)
    flip_a_bit_in_a_page(path)
    with pytest.raises(CampaignError) as info:
        read_perturbations(tmp_path)
    text = str(info.value)
    assert text.startswith(f"{path} is damaged (") and "\n" not in text
    assert text.endswith(
        "run run_perturbed_twins again (it writes the table anew from the campaign's seed)"
    )
