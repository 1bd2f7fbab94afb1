"""A network answers only for the tracks its own runs were drawn from (audit of stop 62)."""

from railsusp.conditions import get_condition
from railsusp.surrogate import load
from railsusp.surrogate.network_set import read_network_set, resolve_network_set
from railsusp.surrogate.training_scope import family_of


def _shipped(condition: str):
    ns = read_network_set(resolve_network_set("c80_k6"))
    return load(ns.bundle(condition))


def test_a_tangent_network_refuses_a_curve_of_its_campaign_s_family():
    """The shipped set's campaign drew radius 250-400 m and cant 0-120 mm in its curves only:
    its tangent network never saw a curve, and predicted |Y| 40 % low in one (R 400 m, 60 mm)
    when its bundle claimed the campaign's family and so accepted the curve."""
    straight = _shipped("straight")
    curved = get_condition("straight").with_changes(curve_radius_m=300.0, cant_mm=110.0)
    fields = {name for name, _, _ in straight.untrained_fields(curved)}
    assert {"curve_radius_m", "cant_mm"} <= fields
    assert straight.untrained_fields(get_condition("straight")) == []
    assert "curve_radius_m" not in straight.track_family()
    assert straight.track_family()["irregularity_classes"] == [4, 6]


def test_a_curve_network_keeps_its_family_s_radius_and_cant():
    curve = _shipped("curve")
    inside = get_condition("curve").with_changes(curve_radius_m=350.0, cant_mm=60.0)
    assert curve.untrained_fields(inside) == []
    outside = get_condition("curve").with_changes(curve_radius_m=600.0, cant_mm=60.0)
    assert [f for f, _, _ in curve.untrained_fields(outside)] == ["curve_radius_m"]


def test_the_family_of_a_condition_drops_the_curve_fields_on_tangent_track():
    ranges = {"irregularity_classes": [4, 6], "curve_radius_m": [250, 400], "cant_mm": [0, 120]}
    assert family_of(ranges, get_condition("straight")) == {"irregularity_classes": [4, 6]}
    assert family_of(ranges, get_condition("curve")) == ranges
