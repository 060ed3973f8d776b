#!/usr/bin/env python3
"""Independent forward kinematics of Archie's legs, product-of-exponentials form.

Regenerates the GOLDEN table of libs/kinematics/tests/archie.rs: for each set of the
script's angles θ0..θ11 (Stepping.sce's order and signs), the pelvis centre's position and
rotation in the right sole's frame, and the left sole's origin in that frame.

The whole robot is one serial chain with the right sole as its base, as Stepping.sce walks
it: up the right (support) leg, θ0 ankle roll to θ5 hip yaw, to the pelvis; then down the
left (swing) leg, θ6 hip yaw to θ11 ankle roll, to the left sole. Each joint is a unit
twist (axis direction ω and a point q on the axis), written in the right sole's frame
(x forward, y left, z up) with all angles zero: legs straight, feet flat, pelvis level.

    pose(pelvis)    = e^(ξ0 θ0) ... e^(ξ5 θ5)  · M_pelvis
    pose(left sole) = e^(ξ0 θ0) ... e^(ξ11 θ11) · M_left

The geometry is the thesis's (Tables 3-4, eqs 38-40, Stepping.sce): ankle roll axis a12
above the sole, a1 up to the ankle pitch axis, a2 to the knee, a3 to the hip pitch axis;
hip pitch, roll and yaw axes meet at the hip joint, d3 inward along the pitch axis (Tables
3-4: links 4 and 5 have a = d = 0; link 3 has d = -d3); the hip bar d6 below the hip
joints, a6 long; the pelvis centre in its middle. Each axis's direction (the sign of its
angle) is read from Stepping.sce's position formulas for small angles with the pelvis
upright, e.g. y1 = y0 - a1 sin θ0, z1 = z0 + a1 cos θ0 is a right-handed turn about +x.

    joint                     ω     q (m)
    θ0  right ankle roll     +x    (0, 0,          a12)
    θ1  right ankle pitch    +y    (0, 0,          a12+a1)
    θ2  right knee           +y    (0, 0,          a12+a1+a2)
    θ3  right hip pitch      +y    (0, 0,          a12+a1+a2+a3)
    θ4  right hip roll       +x    (0, d3,         a12+a1+a2+a3)
    θ5  right hip yaw        -z    (0, d3,         a12+a1+a2+a3)
    θ6  left hip yaw         -z    (0, d3+a6,      a12+a1+a2+a3)
    θ7  left hip roll        +x    (0, d3+a6,      a12+a1+a2+a3)
    θ8  left hip pitch       -y    (0, 2 d3+a6,    a12+a1+a2+a3)
    θ9  left knee            -y    (0, 2 d3+a6,    a12+a1+a2)
    θ10 left ankle pitch     -y    (0, 2 d3+a6,    a12+a1)
    θ11 left ankle roll      +x    (0, 2 d3+a6,    a12)

    M_pelvis = (I, (0, d3+a6/2, a12+a1+a2+a3-d6))
    M_left   = (I, (0, 2 d3+a6, 0))

Usage:
    archie_poe.py                 print the Rust text of the GOLDEN constant
    archie_poe.py --check FILE    compare with the GOLDEN constant in FILE (to 1e-12)

Python 3.11, standard library only.
"""

import argparse
import math
import re
import sys

# Link lengths, m: Stepping.sce's "Initial DH Parameters" (cm): a1 = 12, a2 = 26, a3 = 31,
# d3 = 7.5, a6 = 18, d6 = 5, and a12 = 3.5 (the sole below the ankle roll axis, the
# script's start point z0). The swing leg mirrors the support leg (a9 = a3, a10 = a2,
# a11 = a1, d9 = d3).
A1, A2, A3 = 0.12, 0.26, 0.31
D3, A6, D6 = 0.075, 0.18, 0.05
A12 = 0.035

TOLERANCE = 1e-12

X, Y, Z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)


def neg(v):
    return tuple(-c for c in v)


# Heights of the axes above the sole, and the two legs' planes (y) with all angles zero.
ANKLE_ROLL = A12
ANKLE_PITCH = A12 + A1
KNEE = A12 + A1 + A2
HIP = A12 + A1 + A2 + A3
RIGHT_HIP_Y = D3  # the right hip joint, d3 inward of the right leg
LEFT_HIP_Y = D3 + A6  # the left hip joint, across the bar
LEFT_LEG_Y = 2 * D3 + A6  # the left leg, d3 outward of its hip joint

# (ω, q) of each joint, θ0..θ11, in the right sole's frame at the zero pose.
TWISTS = [
    (X, (0.0, 0.0, ANKLE_ROLL)),
    (Y, (0.0, 0.0, ANKLE_PITCH)),
    (Y, (0.0, 0.0, KNEE)),
    (Y, (0.0, 0.0, HIP)),
    (X, (0.0, RIGHT_HIP_Y, HIP)),
    (neg(Z), (0.0, RIGHT_HIP_Y, HIP)),
    (neg(Z), (0.0, LEFT_HIP_Y, HIP)),
    (X, (0.0, LEFT_HIP_Y, HIP)),
    (neg(Y), (0.0, LEFT_LEG_Y, HIP)),
    (neg(Y), (0.0, LEFT_LEG_Y, KNEE)),
    (neg(Y), (0.0, LEFT_LEG_Y, ANKLE_PITCH)),
    (X, (0.0, LEFT_LEG_Y, ANKLE_ROLL)),
]

IDENTITY = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))

# Zero-pose end frames (rotation, position): the pelvis centre and the left sole.
M_PELVIS = (IDENTITY, (0.0, D3 + A6 / 2, HIP - D6))
M_LEFT = (IDENTITY, (0.0, LEFT_LEG_Y, 0.0))

# The joint sets of GOLDEN (script angles θ0..θ11, rad), with their names.
CASES = [
    ("zero", [0.0] * 12),
    ("frontal, pelvis upright", [0.1, 0.0, 0.0, 0.0, -0.1, 0.0, 0.0, 0.05, 0.3, -0.6, 0.3, -0.05]),
    ("sagittal, pelvis upright", [0.0, 0.2, 0.3, -0.5, 0.0, 0.0, 0.0, 0.0, 0.4, -0.5, 0.1, 0.0]),
    (
        "pelvis upright, with yaw",
        [-0.08, 0.15, 0.1, -0.25, 0.08, 0.3, -0.3, 0.1, 0.2, -0.4, 0.2, -0.1],
    ),
    ("general", [0.1, -0.2, 0.4, 0.15, 0.2, -0.3, 0.1, -0.1, 0.25, -0.5, 0.2, 0.08]),
]


def matmul(a, b):
    return tuple(
        tuple(sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)) for i in range(3)
    )


def matvec(a, v):
    return tuple(sum(a[i][k] * v[k] for k in range(3)) for i in range(3))


def compose(t1, t2):
    """The pose t2 seen through t1: (R1 R2, R1 p2 + p1)."""
    (r1, p1), (r2, p2) = t1, t2
    return matmul(r1, r2), tuple(a + b for a, b in zip(matvec(r1, p2), p1))


def exp_twist(omega, q, theta):
    """e^(ξ θ) for a revolute twist: a turn θ about the line through q along unit ω.

    The rotation is Rodrigues' formula, R = I + sin θ [ω] + (1 - cos θ) [ω]²; a turn about a
    line through q moves the origin by (I - R) q.
    """
    wx, wy, wz = omega
    k = ((0.0, -wz, wy), (wz, 0.0, -wx), (-wy, wx, 0.0))
    k2 = matmul(k, k)
    s, c = math.sin(theta), 1.0 - math.cos(theta)
    r = tuple(
        tuple(IDENTITY[i][j] + s * k[i][j] + c * k2[i][j] for j in range(3)) for i in range(3)
    )
    rq = matvec(r, q)
    return r, tuple(qi - rqi for qi, rqi in zip(q, rq))


def forward(theta):
    """The pelvis (rotation, position) and the left sole's origin, in the right sole's frame."""
    chain = (IDENTITY, (0.0, 0.0, 0.0))
    pelvis = None
    for i, ((omega, q), angle) in enumerate(zip(TWISTS, theta)):
        chain = compose(chain, exp_twist(omega, q, angle))
        if i == 5:
            pelvis = compose(chain, M_PELVIS)
    left = compose(chain, M_LEFT)
    return pelvis[1], pelvis[0], left[1]


def table():
    """One row per case: the angles, the pelvis position, its rotation, the left sole."""
    rows = []
    for _, theta in CASES:
        p, r, left = forward(theta)
        rows.append((list(theta), list(p), [list(row) for row in r], list(left)))
    return rows


def rust(v):
    """A float as a Rust literal, to 16 significant digits (which hides the last bit's
    rounding, e.g. 0.16499999999999998 is printed 0.165); rounding noise below 1e-15 is
    printed as 0.0. Both are far inside the check's 1e-12."""
    if abs(v) < 1e-15:
        return "0.0"
    text = f"{v:.16g}"
    return text if any(c in text for c in ".e") else text + ".0"


def vec(vs):
    return "[" + ", ".join(rust(v) for v in vs) + "]"


def rust_text(rows):
    out = [
        "const GOLDEN: [([f64; 12], [f64; 3], [[f64; 3]; 3], [f64; 3]); 5] = [",
    ]
    for k, ((name, _), (theta, p, r, left)) in enumerate(zip(CASES, rows), start=1):
        angles = "[0.0; 12]" if all(t == 0.0 for t in theta) else vec(theta)
        out += [
            f"    // G{k}: {name}",
            "    (",
            f"        {angles},",
            f"        {vec(p)},",
            "        [" + ", ".join(vec(row) for row in r) + "],",
            f"        {vec(left)},",
            "    ),",
        ]
    out.append("];")
    return "\n".join(out)


NUMBER = re.compile(r"-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?")


def parse_golden(text):
    """The numbers of the GOLDEN constant of a Rust file, grouped as in the table."""
    start = text.find("const GOLDEN")
    if start < 0:
        raise ValueError("no `const GOLDEN` in the file")
    body_start = text.find("= [", start)
    end = text.find("\n];", body_start)
    if body_start < 0 or end < 0:
        raise ValueError("cannot find the body of GOLDEN")
    body = text[body_start + 1 : end]
    body = re.sub(r"//[^\n]*", "", body)
    # Expand Rust's repeat arrays, e.g. [0.0; 12].
    body = re.sub(
        r"\[\s*(" + NUMBER.pattern + r")\s*;\s*(\d+)\s*\]",
        lambda m: "[" + ", ".join([m.group(1)] * int(m.group(2))) + "]",
        body,
    )
    numbers = [float(n) for n in NUMBER.findall(body.replace("_", ""))]
    per_row = 12 + 3 + 9 + 3
    if len(numbers) % per_row:
        raise ValueError(f"GOLDEN holds {len(numbers)} numbers, not a multiple of {per_row}")
    rows = []
    for i in range(0, len(numbers), per_row):
        n = numbers[i : i + per_row]
        rows.append((n[:12], n[12:15], [n[15:18], n[18:21], n[21:24]], n[24:27]))
    return rows


def check(path):
    """One line per disagreement; an exit status of 1 if there is any."""
    with open(path, encoding="utf-8") as f:
        golden = parse_golden(f.read())
    ours = table()
    problems = []
    if len(golden) != len(ours):
        problems.append(f"GOLDEN has {len(golden)} entries, this program {len(ours)}")
    fields = ("theta", "pelvis position", "pelvis rotation", "left sole")
    for k, (g, o) in enumerate(zip(golden, ours), start=1):
        for field, gv, ov in zip(fields, g, o):
            if field == "pelvis rotation":
                pairs = [(f"[{i}][{j}]", gv[i][j], ov[i][j]) for i in range(3) for j in range(3)]
            else:
                pairs = [(f"[{i}]", a, b) for i, (a, b) in enumerate(zip(gv, ov))]
            for index, a, b in pairs:
                if not abs(a - b) <= TOLERANCE:
                    problems.append(
                        f"G{k} {field}{index}: GOLDEN {a!r}, PoE {b!r} (off by {abs(a - b):.3e})"
                    )
    for line in problems:
        print(line)
    if problems:
        return 1
    n = len(golden)
    print(f"GOLDEN of {path}: all {27 * n} numbers of {n} entries agree within {TOLERANCE:g}")
    return 0


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", metavar="FILE", help="the Rust test file holding GOLDEN")
    args = parser.parse_args()
    if args.check:
        sys.exit(check(args.check))
    print(rust_text(table()))


if __name__ == "__main__":
    main()
