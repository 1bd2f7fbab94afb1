"""How a stored result's force-law revision stands to this railsusp's
(railsusp.vehicle.revision): the one classification behind every revision check, and the
words they all use."""

import pytest

import railsusp.vehicle
from railsusp.vehicle.revision import (
    Standing,
    made_with,
    mismatch,
    newer_remedy,
    revision_newer,
    standing,
)


def test_force_law_revisions_compare_as_day_and_number():
    assert revision_newer("2026-11-30.10", "2026-11-30.9")  # as strings: older
    assert revision_newer("2026-12-01", "2026-11-30.2")
    assert not revision_newer("2026-11-30.2", "2026-11-30.2")
    assert not revision_newer("2000-01-01.1")
    assert revision_newer("2099-01-01.1")
    assert not revision_newer("edited by hand")


@pytest.mark.parametrize(
    ("recorded", "expected"),
    [
        (None, Standing.NONE),
        ("2026-11-30.2", Standing.THIS),
        ("2026-11-30.1", Standing.OLDER),
        ("2026-11-30", Standing.OLDER),  # a day's first revision: number 0
        ("2026-11-30.10", Standing.NEWER),
        ("2027-01-01.1", Standing.NEWER),
        ("edited by hand", Standing.OTHER),
        (20261130, Standing.OTHER),  # not text: neither older nor newer
    ],
)
def test_each_recorded_revision_has_one_standing(recorded, expected):
    assert standing(recorded, "2026-11-30.2") is expected


def test_this_railsusps_revision_is_read_when_asked(monkeypatch):
    """Read at call time, not at import: a test (or a session) that moves the model on is
    seen by every check."""
    made = railsusp.vehicle.MODEL_REVISION
    assert standing(made) is Standing.THIS
    monkeypatch.setattr(railsusp.vehicle, "MODEL_REVISION", "2099-01-01.1")
    assert standing(made) is Standing.OLDER
    assert made_with(made) == f"force-law revision {made}, older than this railsusp's 2099-01-01.1"


def test_every_standing_is_said_in_its_own_words(monkeypatch):
    monkeypatch.setattr(railsusp.vehicle, "MODEL_REVISION", "2026-11-30.2")
    assert made_with("2026-11-30.2") == "force-law revision 2026-11-30.2, this railsusp's"
    assert made_with("2026-11-24.2") == (
        "force-law revision 2026-11-24.2, older than this railsusp's 2026-11-30.2"
    )
    assert made_with("2099-01-01.1") == (
        "force-law revision 2099-01-01.1, newer than this railsusp's 2026-11-30.2"
    )
    assert made_with("x") == "force-law revision 'x', not this railsusp's 2026-11-30.2"
    assert made_with(None) == (
        "force laws older than any recorded force-law revision (it records none: made before "
        "revisions were recorded, on 2026-11-30; this railsusp's is 2026-11-30.2)"
    )
    assert newer_remedy("2099-01-01.1") == (
        "use it with the railsusp that made it (force-law revision 2099-01-01.1 or later)"
    )


def test_a_mismatch_is_said_with_the_remedy_its_standing_takes(monkeypatch):
    monkeypatch.setattr(railsusp.vehicle, "MODEL_REVISION", "2026-11-30.2")
    assert mismatch("2026-11-30.2", "train again") is None
    assert mismatch("2026-11-24.2", "train again") == (
        "force-law revision 2026-11-24.2, older than this railsusp's 2026-11-30.2: train again"
    )
    assert mismatch(None, "train again").endswith("this railsusp's is 2026-11-30.2): train again")
    assert mismatch("2099-01-01.1", "train again") == (
        f"{made_with('2099-01-01.1')}: {newer_remedy('2099-01-01.1')}"
    )
