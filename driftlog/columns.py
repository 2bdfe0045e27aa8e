"""Named columns of the arrays the kernels share: one name per index, never a raw number.

Rows are logs (state, flow sample, parameters, drag linearisation), mesh nodes (snapshot node
values) or contacts (contact result, capsule).  The kernels index with these module-level
integers, which numba compiles as constants: naming a column costs nothing.  The modules that
own each array (``logs``, ``flow``, ``physics``, ``contact.geometry``) re-export theirs.
"""

# --------------------------------------------------------------------- log state (n, NSTATE)
# centre, axis angle, velocity of the centre, angular velocity (docs/model.md section 5)
X, Y, THETA, UB, VB, OMEGA = range(6)
NSTATE = 6
STATE_NAMES = ("x", "y", "theta", "u", "v", "omega")  # in column order, as in trajectory files
POSITION = slice(X, THETA + 1)  # x, y, theta
VELOCITY = slice(UB, OMEGA + 1)  # u, v, omega: the rates of POSITION, in the same order
# a velocity row (n, 3) = state[:, VELOCITY] (the contact solvers' generalised velocity)
GU, GV, GOMEGA = UB - UB, VB - UB, OMEGA - UB

# --------------------------------------------------------------------- flow sample (n, NVAR)
# depth, velocity, local dU/dt, velocity gradient J_ij = dU_i/dx_j, free-surface slope, level
H, U, V, DUDT, DVDT, DUDX, DUDY, DVDX, DVDY, DETADX, DETADY, ETA = range(12)
NVAR = 12
# flag of a sampled point
OUTSIDE, DRY, WET = 0, 1, 2

# --------------------------------------------------------------------- snapshot node values
# (n_nodes, NQ) per snapshot: values, then the least-squares gradients of u, v and eta
Q_H, Q_U, Q_V, Q_ETA, Q_UX, Q_UY, Q_VX, Q_VY, Q_EX, Q_EY = range(10)
NQ = 10

# regular-grid point values (n_points, NG) per snapshot (driftlog.gridflow): depth, velocity,
# water level
G_H, G_U, G_V, G_ETA = range(4)
NG = 4

# --------------------------------------------------------------------- per-log parameters
# (n, NPARAM): length, radius, density, volume, mass, inertia, volume-equivalent diameter,
# sphericity, Ganser's K2, flotation depth; then constants of the force kernels that depend
# only on the log's geometry (driftlog.physics.log_parameters): the end-on area pi r^2, the
# broadside area 2 r L, 1 / (3 d_v) and (2/3) / sqrt(psi) (Ganser's K1 = 1 / (d_n / (3 d_v)
# + (2/3) / sqrt(psi))), d_v K2, Ganser's area pi d_v^2 / 4, 1 / K1 of the broadside area
# (the resistance torque's), and r L^4 / 32 (the torque's lever integral, times rho)
(P_L, P_R, P_RHOB, P_VOL, P_MASS, P_INERTIA, P_DV, P_PSI, P_K2, P_HSTAR, P_AEND, P_ASIDE,
 P_INV3DV, P_KSPH, P_DVK2, P_AGANSER, P_QSIDE, P_KTORQUE) = range(18)
NPARAM = 18

# --------------------------------------------------------------------- drag linearisation
# (n, NLIN): drag rates along and across the relative velocity, its direction, rotational rate
L_PAR, L_PERP, L_WX, L_WY, L_ROT = range(5)
NLIN = 5

# --------------------------------------------------------------------- contacts
# contact result (k, NRES): signed gap, unit normal, contact point
GAP, NX, NY, CX, CY = range(5)
NRES = 5
# capsule (k, NCAP): the segment [a, b] and the radius
CAP_AX, CAP_AY, CAP_BX, CAP_BY, CAP_R = range(5)
NCAP = 5
