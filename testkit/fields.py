"""Solved fields changed for a test, leaving the original as it was."""

from __future__ import annotations

import dataclasses


def with_curve(field, k: int, **changes):
    """A copy of a SolvedField whose prepared curve k has ``changes``
    (dataclasses.replace of the Curve: sigma=, points=, ...); the field and
    its network are not touched, so a shared solve stays as it was."""
    net = field.network
    curves = list(net.curves)
    curves[k] = dataclasses.replace(curves[k], **changes)
    return dataclasses.replace(field, network=dataclasses.replace(net, curves=curves))
