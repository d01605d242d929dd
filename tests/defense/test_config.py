import pytest

from testbed.defense.config import PAPER_CUSUM, PAPER_MODE, DefenseConfig
from testbed.defense.registry import make_defense


def test_defaults_follow_the_paper_but_the_cusum_is_the_refit_one():
    c = DefenseConfig()
    assert c.ar_decel == 4.0 and (c.b, c.tau) == (0.2, 2.0)
    paper = DefenseConfig(**PAPER_MODE)
    assert PAPER_CUSUM == {"b": 0.6, "tau": 0.1} and (paper.b, paper.tau) == (0.6, 0.1)


def test_naive_ar_brakes_at_apollos_planner_bound_not_the_cars_brake_limit():
    # NaiveAR models Apollo's in-lane stop (paper §5.3): Apollo's planner never asks for more than 4.5 m/s²
    c = DefenseConfig()
    assert c.max_decel == 4.5 and c.max_decel > c.ar_decel
    assert make_defense("ld3-naive-ar", c).stop_decel is None  # only once alarmed


def test_from_dict_accepts_ints_for_floats():
    c = DefenseConfig.from_dict({"b": 1, "tau": 0.2, "window": 10, "ar_decel": 2.5})
    assert (c.b, c.tau, c.window, c.ar_decel) == (1.0, 0.2, 10, 2.5)
    assert isinstance(c.b, float)


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"bee": 0.6}, "unknown"),
        ({"lam": 1.5}, "lam"),
        ({"window": 0}, "window"),
        ({"window": 2.5}, "window"),
        ({"tau": -0.1}, "tau"),
        ({"ar_decel": 0}, "ar_decel"),
        ({"b": "0.6"}, "b"),
        ({"b": True}, "b"),
        ({"p_ld": float("nan")}, "p_ld"),
        ({"heading": "gps"}, "heading"),
        ({"heading": 1}, "heading"),
        ({"p_source": "guess"}, "p_source"),
        ({"heading_clamp": 0.0}, "heading_clamp"),
        ({"r_power": 9.0}, "r_power"),
        ({"heading": "msf", "heading_clamp": 0.03}, "acts only with heading"),
        ({"heading": "lane", "heading_clamp": 0.03}, "acts only with heading"),
    ],
)
def test_from_dict_rejects_bad_tables(table, message):
    with pytest.raises(ValueError, match=message):
        DefenseConfig.from_dict(table)


def test_factory_names_and_unknown_name():
    for name in ("ld3", "ld3-naive-ar", "savior", "none"):
        assert make_defense(name).name == name  # each with its own model's defaults
    assert make_defense("ld3", DefenseConfig(b=0.5)).config.b == 0.5
    with pytest.raises(ValueError, match=r"unknown defense 'ld4'.*ld3, ld3-naive-ar, savior, none"):
        make_defense("ld4")


def test_heading_clamp_is_accepted_where_it_acts():
    assert DefenseConfig.from_dict({"heading": "ld", "heading_clamp": 0.03}).heading_clamp == 0.03
    assert DefenseConfig.from_dict({"heading_clamp": 0.04}).heading == "fused"  # the default heading uses it
