"""The exposure trajectory of one frame: two poses, linear motion in between, K sub-poses.

``T(eta)`` (paper eq. 4) slerps the rotation and lerps the translation between the pose at the
start of the exposure, ``T_0``, and at its end, ``T_tau``. We interpolate the camera-to-world
poses (so the camera *centre* moves on a straight line, the physical constant-velocity model
that the data generator also uses) and hand world-to-camera matrices to the rasteriser.

The sub-pose times ``eta_0 = 0 < eta_1 < ... < eta_K = tau`` split the exposure so that every
segment holds about the same number of events (uniform when there are too few events).
"""

from __future__ import annotations

import numpy as np

from egs_bench.geometry.lie import so3_exp, so3_left_jacobian, so3_left_jacobian_inv, so3_log


def exposure_path(pose0_cw: np.ndarray, pose1_cw: np.ndarray, fractions: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Sub-poses of an exposure trajectory and their Jacobians w.r.t. the end poses' twists.

    Rotation slerped, camera centre on a straight line (the model of ``T(eta)`` above), in
    float64 on the host. With ``Q_j, t_j`` the rotation and translation of the
    world-to-camera end poses, ``omega = Log(Q_0 Q_1^T)`` and ``c_j = -Q_j^T t_j`` the camera
    centres, the sub-pose at fraction ``f`` is ``Q(f) = Exp(-f omega) Q_0``,
    ``t(f) = -Q(f) ((1 - f) c_0 + f c_1)``.

    Jacobian: perturbing the end poses by left twists ``T_j <- Exp(xi_j) T_j``
    (``xi = (rho, phi)``) perturbs sub-pose ``k`` by a left twist ``eta_k = A_k (xi_0, xi_1)``
    with, to first order (exact derivatives at ``xi = 0``), ``E = Exp(-f omega)``:
    ``rho_k = (1 - f) E rho_0 + f Exp((1 - f) omega) rho_1`` and
    ``phi_k = (E - f J_l(-f omega) J_l^-1(omega)) phi_0 + f J_l(-f omega) J_r^-1(omega) phi_1``
    (first-order BCH on ``Log(Exp(phi_0) Exp(omega) Exp(-phi_1))``; centres move by
    ``-Q_j^T rho_j``).

    Args:
        pose0_cw, pose1_cw: world-to-camera poses [4, 4] at the exposure's start and end.
        fractions: [M] in [0, 1]; a single fraction 1 means "no blur model": the sub-pose is
            ``pose1_cw`` alone.

    Returns:
        ``viewmats`` [M, 4, 4] (world-to-camera) and ``jacobian`` [M, 6, 12] mapping the stacked
        end twists ``(rho_0, phi_0, rho_1, phi_1)`` to each sub-pose's twist ``(rho_k, phi_k)``.
    """
    f = np.asarray(fractions, dtype=np.float64).reshape(-1)
    m = f.shape[0]
    p0 = np.asarray(pose0_cw, dtype=np.float64)
    p1 = np.asarray(pose1_cw, dtype=np.float64)
    jac = np.zeros((m, 6, 12))
    if m == 1 and f[0] == 1.0:
        jac[0, :, 6:] = np.eye(6)
        return p1[None].copy(), jac
    q0, t0, q1, t1 = p0[:3, :3], p0[:3, 3], p1[:3, :3], p1[:3, 3]
    rel = q0 @ q1.T
    omega = so3_log(rel)
    e = so3_exp(-f[:, None] * omega)  # [M, 3, 3]
    c0, c1 = -q0.T @ t0, -q1.T @ t1
    centres = (1 - f)[:, None] * c0 + f[:, None] * c1
    views = np.zeros((m, 4, 4))
    views[:, :3, :3] = e @ q0
    views[:, :3, 3] = -(views[:, :3, :3] @ centres[..., None])[..., 0]
    views[:, 3, 3] = 1.0
    jl = so3_left_jacobian(-f[:, None] * omega)
    fc = f[:, None, None]
    jac[:, 0:3, 0:3] = (1 - fc) * e
    jac[:, 0:3, 6:9] = fc * (e @ rel)  # Exp((1 - f) omega)
    jac[:, 3:6, 3:6] = e - fc * (jl @ so3_left_jacobian_inv(omega))
    jac[:, 3:6, 9:12] = fc * (jl @ so3_left_jacobian_inv(-omega))
    return views, jac


def subpose_fractions(event_t_us: np.ndarray, t_start_us: int, t_end_us: int, n_segments: int,
                      min_events: int | None = None) -> np.ndarray:
    """Fractions ``eta_k / tau`` [K+1] of the exposure at the sub-pose times.

    Interior boundaries are the event-count quantiles, so each of the ``K`` segments holds about
    the same number of events; with fewer than ``min_events`` (default ``4 K``) events in the
    window the split is uniform. Boundaries are forced strictly increasing.

    Args:
        event_t_us: event timestamps (int64 us) inside ``[t_start_us, t_end_us)``.
        t_start_us, t_end_us: exposure window.
        n_segments: K >= 1.
    """
    if n_segments < 1:
        raise ValueError("n_segments must be >= 1")
    tau = float(t_end_us - t_start_us)
    uniform = np.linspace(0.0, 1.0, n_segments + 1)
    if tau <= 0:
        return uniform
    need = 4 * n_segments if min_events is None else min_events
    t = np.asarray(event_t_us, dtype=np.float64)
    t = t[(t >= t_start_us) & (t <= t_end_us)]
    if n_segments == 1 or len(t) < max(need, 1):
        return uniform
    inner = (np.quantile(t, uniform[1:-1]) - t_start_us) / tau
    frac = np.concatenate([[0.0], np.clip(inner, 0.0, 1.0), [1.0]])
    # Keep segments non-degenerate (a burst of events at one instant would collapse them).
    min_gap = 0.02 / n_segments
    for k in range(1, n_segments + 1):
        frac[k] = max(frac[k], frac[k - 1] + min_gap)
    if frac[-1] > 1.0 + 1e-12:  # pushed past the end: rescale the tail back into [0, 1]
        frac = frac / frac[-1]
    frac[-1] = 1.0
    return frac


def segment_edges_us(fractions: np.ndarray, t_start_us: int, t_end_us: int) -> np.ndarray:
    """Sub-pose times in microseconds [K+1] (int64), first = t_start, last = t_end."""
    edges = np.round(t_start_us + fractions * (t_end_us - t_start_us)).astype(np.int64)
    edges[0], edges[-1] = t_start_us, t_end_us
    return edges
