"""Strategy C's wrist-pose NLP: where the closed-form pose is feasible it is the minimum the SQP finds."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from softsig_service.objects import box, builtin_object
from softsig_service.planning import planning_model, solve_wrist_pose
from softsig_service.planning import wrist_pose as wp


def _sqp(model_name: str, obj_center: np.ndarray, closing: np.ndarray, offset: float) -> np.ndarray:
    """The SQP's answer from the closed-form pose raised by 0.1 mm (the path taken when it is infeasible)."""
    model = planning_model(model_name)
    u = model.signature.axis / np.linalg.norm(model.signature.axis)
    pa, P = model.placement_point("C", "open_centre"), model.points_open
    a = closing[:2] / np.linalg.norm(closing[:2])
    x0, _ = wp._closed_form(wp.hand_rotation(0.0, 0.0, 0.0) @ u, pa, P, obj_center, a, 0.0, 0.005, offset)
    x0[2] += 1e-4
    solver, n = wp._solver(len(P))
    params = np.concatenate([u, pa, P.reshape(-1), obj_center, a, [0.0, 0.005]])
    sol = solver(x0=x0, p=params, lbx=[-np.inf] * 4 + [-wp.MAX_TILT] * 2, ubx=[np.inf] * 4 + [wp.MAX_TILT] * 2,
                 lbg=[0.0] * n + [wp.REACH[0] ** 2], ubg=[np.inf] * n + [wp.REACH[1] ** 2])  # fmt: skip
    assert solver.stats()["success"]
    return np.asarray(sol["x"]).ravel()


@settings(max_examples=15, deadline=None)
@given(x=st.floats(0.35, 0.6), y=st.floats(-0.25, 0.25), yaw=st.floats(-math.pi, math.pi))
def test_the_closed_form_minimum_is_the_sqp_minimum(x: float, y: float, yaw: float) -> None:
    obj = builtin_object("box", x=x, y=y, yaw=yaw)
    model = planning_model("pisa_iit_softhand")
    sols = solve_wrist_pose(model.signature.axis, model.placement_point("C", "open_centre"), model.points_open,
                            obj.center, obj.o2)  # fmt: skip
    for sol, offset in zip(sols, (0.0, math.pi), strict=True):
        assert sol.success and sol.status == "closed_form" and sol.iterations == 0
        w = _sqp("pisa_iit_softhand", obj.center, obj.o2, offset)
        np.testing.assert_allclose([*sol.T_world_hand[:3, 3], sol.roll, sol.pitch], [*w[:3], w[4], w[5]], atol=1e-9)
        assert abs(math.remainder(sol.yaw - w[3], 2 * math.pi)) <= 1e-9


def test_a_flat_object_takes_the_sqp_and_keeps_the_hand_above_the_table() -> None:
    """A 6 mm box: the closed-form pose would put the fingertips under the table, so the SQP solves it."""
    obj = box((0.06, 0.03, 0.006), 0.1, x=0.45, y=0.1, yaw=0.3)
    model = planning_model("pisa_iit_softhand")
    sols = solve_wrist_pose(model.signature.axis, model.placement_point("C", "open_centre"), model.points_open,
                            obj.center, obj.o2)  # fmt: skip
    for sol in sols:
        assert sol.success and sol.status != "closed_form" and sol.iterations >= 1
        assert sol.clearance >= 0.005 - 1e-6  # the lowest reference point keeps the margin above the table
        assert sol.alignment_error <= 1e-6


def test_the_closed_form_check_and_the_compiled_nlp_share_one_cost_and_constraints() -> None:
    """The closed-form check evaluates the NLP's cost and constraints in numpy; at random poses and parameters
    (tilted ones included) they equal CasADi's evaluation of the same expressions the solver is built from."""
    import casadi as ca

    n = 5
    w = ca.SX.sym("w", 6)
    p = ca.SX.sym("p", 3 + 3 + 3 * n + 3 + 2 + 2)
    P_sym = ca.reshape(p[6 : 6 + 3 * n], 3, n)
    k = 6 + 3 * n
    R_sym = wp.hand_rotation(w[3], w[4], w[5], lib=ca)
    f, heights, reach = wp._cost_and_constraints(
        w, R_sym, p[0:3], p[3:6], (R_sym @ P_sym)[2, :].T, p[k : k + 3], p[k + 3 : k + 5], p[k + 5], p[k + 6]
    )
    compiled = ca.Function("f_g", [w, p], [f, ca.vertcat(heights, reach)])
    rng = np.random.default_rng(4)
    for _ in range(50):
        x = np.concatenate([rng.uniform(-0.5, 0.5, 3), rng.uniform(-math.pi, math.pi, 1), rng.uniform(-0.2, 0.2, 2)])
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        pa, P, c = rng.uniform(-0.1, 0.1, 3), rng.uniform(-0.1, 0.1, (n, 3)), rng.uniform(-0.3, 0.3, 3)
        a = rng.normal(size=2)
        a /= np.linalg.norm(a)
        table, margin = rng.uniform(-0.1, 0.1), 0.005
        params = np.concatenate([u, pa, P.reshape(-1), c, a, [table, margin]])
        f_ca, g_ca = compiled(x, params)
        R = wp.hand_rotation(x[3], x[4], x[5])
        f_np, h_np, r_np = wp._cost_and_constraints(x, R, u, pa, P @ R[2], c, a, table, margin)
        np.testing.assert_allclose(float(f_np), float(f_ca), rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(np.append(h_np, r_np), g_ca.full().ravel(), rtol=1e-12, atol=1e-15)
