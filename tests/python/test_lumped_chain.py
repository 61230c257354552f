"""A modal boom against the lumped chain it was made from (docs/flexible.md,
"Against a lumped chain"; issue 49's equivalence check): the bus turning at
0.01 rad/s about z, the boom bent in its first mode, 10 s with RK4 at
1e-4 s on both sides. nudyn's linear modal model lacks terms of second order
in the bending, so the difference falls by about 100 times for a bending 10
times smaller; a first-order term missing would show as 10 times."""

from __future__ import annotations

from nudyn_validation.lumped_chain import Boom, compare


def test_the_difference_is_second_order_in_the_bending(nudyn):
    larger, smaller = compare(nudyn, Boom(), [1e-2, 1e-3], spin=0.01)
    print(larger, smaller)
    assert larger["bus"] < 1e-5 and larger["hinges"] < 1e-5, larger
    assert larger["bus"] / smaller["bus"] > 50, (larger, smaller)
    assert larger["hinges"] / smaller["hinges"] > 50, (larger, smaller)


def test_with_a_hinged_panel_at_the_tip_the_difference_is_second_order(nudyn):
    """The chain carries a panel on a hinge at its tip, the modal body the
    same panel at its node "tip" (docs/flexible.md, "Child bodies at
    nodes"), both started with the panel turned by the amplitude: the
    panel's coupling to the modes through the node is right to first order.
    (Hung from the body's undeformed frame instead, the panel's difference
    falls only 10 times per decade.)"""
    larger, smaller = compare(nudyn, Boom(panel="hinge"), [1e-2, 1e-3], spin=0.01)
    print(larger, smaller)
    assert larger["bus"] < 1e-3 and larger["hinges"] < 1e-3 and larger["panel"] < 1e-2, larger
    for quantity in ["bus", "hinges", "panel"]:
        assert larger[quantity] / smaller[quantity] > 50, (quantity, larger, smaller)


def test_with_a_panel_welded_at_the_tip_the_difference_is_second_order(nudyn):
    """The same panel welded at the tip (docs/flexible.md, "Bodies welded at
    nodes"): its inertia, off the node, joins the node's."""
    larger, smaller = compare(nudyn, Boom(panel="weld"), [1e-2, 1e-3], spin=0.01)
    print(larger, smaller)
    assert larger["bus"] < 1e-4 and larger["hinges"] < 1e-3, larger
    for quantity in ["bus", "hinges"]:
        assert larger[quantity] / smaller[quantity] > 50, (quantity, larger, smaller)
