"""What a solve reports (solver/report.py): one serialisation, read back
whole, and the singular-face counts a solve headlines."""

from __future__ import annotations

import json

import numpy as np

from solver import Report
from solver.field.volume3d import LMIteration, LMReport
from solver.network.curve_ends import EndBend
from solver.network.intake import CurveRepair
from solver.surface.corners import CornerChoice


def a_report() -> Report:
    """A report with every part filled, numpy scalars included (as a solve
    leaves them in sizes and metrics)."""
    its = [LMIteration(k, 10.0 / (k + 1), 9.0 / (k + 1), 0.1, 1e-3, 1e-2, 40 + k, True, 0.5, step=0.1 * k,
                       newton=k > 1) for k in range(4)]
    lm = LMReport("zero", its, converged=True, capped=False, reason="energy decrease below tolerance",
                  seconds=2.0, setup_seconds=0.3, preconditioner_builds=2)
    end = EndBend("end", 12.0, 0.8, position=(np.float64(1.0), 0.0, 2.5), input_angle_deg=31.0, gap="cut back",
                  gap_h=0.4)
    repair = CurveRepair(3, "axial 0", 40, 21, 2, True, 0.31, 35.0, 8.0, corners=1, ends=[end], note="",
                         joined=[("start", 0.2)], pieces=[3, 4])
    corner = CornerChoice(12, (1.0, 0.0, 0.5), (90.0, 130.0, 140.0), (1, 1, 2), 0, 1, "chosen", True)
    return Report(stage_seconds={"validate": 0.1, "tetmesh": 2.5}, sizes={"tets": np.int64(1234), "vertices": 300},
                  lm=lm, metrics={"monodromy_mean_deg": np.float64(0.01), "omega_singular_faces": 12,
                                  "omega_spurious_singular_faces": 1, "omega_missing_singular_faces": 0,
                                  "matching_disagreements": np.int64(2)},
                  edge_length=0.3, repairs=[repair], repair_scale=0.3, mesher="fTetWild", corners=[corner],
                  status="converged", status_reason="energy decrease below tolerance")


def test_a_report_is_read_back_whole_through_json():
    r = a_report()
    d = json.loads(json.dumps(r.to_dict()))  # plain JSON types, no default= needed
    back = Report.from_dict(d)
    assert back.to_dict() == d
    assert back.summary() == r.summary()
    assert back.lm.n_iterations == 3 and back.lm.final.newton and back.lm.preconditioner_builds == 2
    assert back.repairs[0].ends[0].position == (1.0, 0.0, 2.5) and back.repairs[0].changed
    assert back.repairs[0].text() == r.repairs[0].text()
    assert back.corners[0].text() == r.corners[0].text()
    assert back.converged and d["converged"] is True
    # a result file adds the options; they are not the report's
    assert Report.from_dict({**d, "options": {"penalty": 1000}}) == back


def test_a_report_without_lm_or_repairs():
    r = Report(sizes={"tets": 10})
    d = r.to_dict()
    assert "lm" not in d and d["converged"] is False
    assert Report.from_dict(json.loads(json.dumps(d))) == r


def test_singular_face_counts_are_the_omega_matchings():
    assert a_report().singular_face_counts() == {"singular": 12, "spurious": 1, "missing": 0, "closest_differs": 2}
    assert Report().singular_face_counts() == {"singular": 0, "spurious": 0, "missing": 0, "closest_differs": 0}
