"""Batch least-squares check of a converted Husky bag: how well do the GNSS fixes fix the radii?

Dead reckoning from the rear wheel speeds with left/right radius errors ``d_l``, ``d_r``:
``v = ((r + d_l) w_l + (r + d_r) w_r) / 2``, ``psi' = ((r + d_r) w_r - (r + d_l) w_l) / l_T``
(the estimator's eq. 6), integrated along the mid heading of each wheel-speed interval from an
initial pose ``(e0, n0, psi0)``; the five parameters are fitted to the GNSS east/north of the
whole drive and of its halves and thirds (no process noise, GNSS antenna at base_link as in
the bag's ``vehicle.yaml``). Printed: the fits, the residual RMS (m), the residual
autocorrelation time (first lag below 1/e, s) and the formal std of the radius errors for white
GNSS noise of the reported 0.8 m (docs/data_husky.md).

    python scripts/husky_batch_fit.py BAG
"""

from __future__ import annotations

import argparse
import itertools
import math

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from tire_estimation.bag.reader import read_bag
from tire_estimation.core.geodesy import LocalTangentPlane

F64 = NDArray[np.float64]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("bag")
    args = ap.parse_args()
    data = read_bag(args.bag)
    veh, ws, gnss = data.vehicle, data.wheel_speeds, data.gnss
    if ws is None or gnss is None:
        raise SystemExit("the bag needs /vehicle/wheel_speeds and /gnss/fix")
    r, lt = veh.nominal_tire_radius_m, veh.track_width_m
    t0 = int(ws.t_ns[0])
    t_w = (ws.t_ns - t0) * 1e-9
    dt = np.diff(t_w)
    w_l, w_r = ws.wheel_speed_rad_s[:-1, 2], ws.wheel_speed_rad_s[:-1, 3]
    ltp = LocalTangentPlane(float(gnss.lat_deg[0]), float(gnss.lon_deg[0]), float(gnss.alt_m[0]))
    east, north, _ = ltp.to_enu(gnss.lat_deg, gnss.lon_deg, gnss.alt_m)
    t_f = (gnss.t_ns - t0) * 1e-9

    def track(p: F64) -> tuple[F64, F64]:
        e0, n0, psi0, d_l, d_r = p
        v = 0.5 * ((r + d_l) * w_l + (r + d_r) * w_r)
        yaw_rate = ((r + d_r) * w_r - (r + d_l) * w_l) / lt
        psi = psi0 + np.r_[0.0, np.cumsum(yaw_rate * dt)]
        mid = psi[:-1] + 0.5 * yaw_rate * dt
        e = e0 + np.r_[0.0, np.cumsum(v * np.cos(mid) * dt)]
        n = n0 + np.r_[0.0, np.cumsum(v * np.sin(mid) * dt)]
        return e, n

    def residual(p: F64, sel: NDArray[np.bool_]) -> F64:
        e, n = track(p)
        return np.r_[
            np.interp(t_f[sel], t_w, e) - east[sel], np.interp(t_f[sel], t_w, n) - north[sel]
        ]

    def fit(sel: NDArray[np.bool_]) -> tuple[F64, F64, F64]:
        best = None
        for psi0 in np.radians(np.arange(0.0, 360.0, 30.0)):
            p0 = np.array([east[sel][0], north[sel][0], psi0, 0.0, 0.0])
            sol = least_squares(residual, p0, args=(sel,), x_scale=[1.0, 1.0, 0.1, 1e-3, 1e-3])
            if best is None or sol.cost < best.cost:
                best = sol
        assert best is not None
        res = residual(best.x, sel).reshape(2, -1)
        return best.x, res, best.jac

    everything = np.ones(t_f.size, dtype=bool)
    p, res, jac = fit(everything)
    cov = np.linalg.inv(jac.T @ jac) * 0.8**2
    print(
        f"whole drive: d_l {1e3 * p[3]:+.2f} mm, d_r {1e3 * p[4]:+.2f} mm, "
        f"residual RMS {math.sqrt(float(np.mean(np.sum(res**2, axis=0)))):.2f} m; "
        f"formal std for white 0.8 m noise {1e3 * math.sqrt(cov[3, 3]):.2f} / "
        f"{1e3 * math.sqrt(cov[4, 4]):.2f} mm"
    )
    period = float(np.median(np.diff(t_f)))
    for axis, x in zip(("east", "north"), res, strict=True):
        x = x - x.mean()
        acf = np.correlate(x, x, "full")[x.size - 1 :]
        lag_s = period * float(np.argmax(acf / acf[0] < 1 / math.e))
        print(f"  {axis} residual autocorrelation time {lag_s:.1f} s")
    end = float(t_f[-1]) + 1.0
    for parts in (2, 3):
        edges = np.linspace(0.0, end, parts + 1)
        for lo, hi in itertools.pairwise(edges):
            sel = (t_f >= lo) & (t_f < hi)
            p, res, _ = fit(sel)
            rms = math.sqrt(float(np.mean(np.sum(res**2, axis=0))))
            print(
                f"{lo:5.0f}-{hi:3.0f} s: d_l {1e3 * p[3]:+.2f} mm, d_r {1e3 * p[4]:+.2f} mm, "
                f"residual RMS {rms:.2f} m"
            )


if __name__ == "__main__":
    main()
