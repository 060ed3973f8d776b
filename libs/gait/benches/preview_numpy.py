"""ZMP preview control (Kajita 2003) in Python/NumPy, the way published generators write it:
gains from the discrete Riccati equation, then per tick and axis the integral, state and
preview terms and the cart-table update. Prints the time per tick (x and y) of a walk's
reference; `scripts/bench gait` runs it beside the Rust controller."""

import argparse
import json
import time

import numpy as np


def gains(dt, z_c, g, n, q_e=1.0, r=1e-6):
    a = np.array([[1.0, dt, dt * dt / 2], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    b = np.array([[dt**3 / 6], [dt * dt / 2], [dt]])
    c = np.array([[1.0, 0.0, -z_c / g]])
    # The augmented system (the integral of the tracking error, then the state).
    a1 = np.block([[np.eye(1), c @ a], [np.zeros((3, 1)), a]])
    b1 = np.vstack([c @ b, b])
    i1 = np.array([[1.0, 0.0, 0.0, 0.0]]).T
    q = q_e * (i1 @ i1.T)
    p = q.copy()
    for _ in range(100000):
        k = np.linalg.solve(r + b1.T @ p @ b1, b1.T @ p @ a1)
        nxt = a1.T @ p @ a1 - a1.T @ p @ b1 @ k + q
        if np.max(np.abs(nxt - p)) < 1e-14 * max(1.0, np.max(np.abs(p))):
            p = nxt
            break
        p = nxt
    s = r + b1.T @ p @ b1
    k = np.linalg.solve(s, b1.T @ p @ a1)
    gi, gx = k[0, 0], k[0, 1:]
    # The reference enters the integral as -I1 r(k+1): the optimal feedforward on r(k+j) is
    # G_p(j) = -S^-1 B1' (Ac')^(j-1) P I1, so that G_p(1) = -G_i.
    ac = a1 - b1 @ k
    x = p @ i1
    gp = np.zeros(n)
    for j in range(n):
        gp[j] = -np.linalg.solve(s, b1.T @ x)[0, 0]
        x = ac.T @ x
    return a, b[:, 0], c[0], gi, gx, gp


def reference(dt, ticks, pad):
    t = np.minimum(np.arange(ticks + pad), ticks) * dt
    step = np.floor(t / 1.25)
    ramp = np.clip((t - step * 1.25 - 1.0) / 0.25, 0.0, 1.0)
    side = lambda s: np.where(s % 2 == 0, 0.1, -0.1)
    return 0.25 * (step + ramp), side(step) * (1 - ramp) + side(step + 1) * ramp


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--horizon", type=float, default=1.6)
    ap.add_argument("--z-c", type=float, default=0.4)
    ap.add_argument("--ticks", type=int, default=4000)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--dt", type=float, default=0.005)
    ap.add_argument("--q-e", type=float, default=1.0)
    ap.add_argument("--r", type=float, default=1e-6)
    ap.add_argument("--gains", action="store_true", help="print the gains as JSON, run nothing")
    args = ap.parse_args()
    dt, g = args.dt, 9.80665
    n = int(round(args.horizon / dt))
    a, b, c, gi, gx, gp = gains(dt, args.z_c, g, n, args.q_e, args.r)
    if args.gains:
        print(json.dumps({"gi": gi, "gx": list(gx), "gp": list(gp)}))
        return
    refs = reference(dt, args.ticks, n + 1)
    best = []
    for _ in range(args.rounds):
        t0 = time.perf_counter()
        for ref in refs:
            x = np.zeros(3)
            e = 0.0
            for k in range(args.ticks):
                e += c @ x - ref[k]
                u = -gi * e - gx @ x - gp @ ref[k + 1 : k + 1 + n]
                x = a @ x + b * u
        best.append((time.perf_counter() - t0) / args.ticks)
    best.sort()
    print(f"ns_per_tick={best[len(best) // 2] * 1e9:.0f} numpy={np.__version__}")


if __name__ == "__main__":
    main()
