/*
 * slip_mode 1: the friction solver of the dynamic regime (the formulation is the note at the top
 * of slip.c), in linear time.
 *
 * Linear time (the chain). M and A = J M^-1 J^T are dense (a trailer's position depends on every
 * heading ahead of it): forming A costs O(n^3) and one Gauss-Seidel sweep on it O(n^2). Neither is
 * needed, as every product with M, M^-1, J and J^T is a sweep along the chain. For yaw rates z,
 * with D_k = F_k + R_k and n_k the normals, the velocities of trailer k's front hitch and axle are
 *   h_1 = 0,  h_{k+1} = h_k - D_k z_k n_k,  a_k = h_k - F_k z_k n_k   (= -sum_j L_kj z_j n_j)
 * so  z^T M z = sum_k (m_k |a_k|^2 + I_k z_k^2)  and  (J z)_k = n_k.a_k. Hence:
 * - J z is a forward sweep, J^T lambda a backward one (suffix sums of lambda_i n_i), and J is lower
 *   triangular with diagonal -F_k, so J^-T is a back substitution: O(n) each.
 * - M z = f minimizes z^T M z / 2 - f.z, a linear-quadratic problem along the chain whose state is
 *   the 2-vector h: dynamic programming from trailer n back to 1 with the cost-to-go
 *   h^T P_k h / 2 + p_k.h (a Riccati recursion on 2 x 2 matrices, P_{n+1} = 0), then the
 *   minimizing z_k = (b_k.h_k + gamma_k) / alpha_k forward from h_1 = 0. P, b and alpha depend on
 *   the headings only (once per substep), p and gamma on f: O(n) per solve. This is the
 *   articulated-body elimination of the block-tridiagonal Newton-Euler and hitch equations of the
 *   trailers, from the tail to the robot.
 * - The equality problem of a partition (the wheels in S stick, (J z)_i = -u_free_i; the others
 *   carry lambda_i = +-lim_i) is  min z^T M z / 2 - (J_L^T lambda_L).z  subject to the sticking
 *   rows. M is taken at the start headings and J at the end headings, so the same dynamic
 *   programming runs on the state x = (h, h*), h* the recursion through the end normals n*_k:
 *   P_k is 4 x 4; a sliding trailer minimizes over z_k as above, a sticking one has z_k fixed by
 *   its row, z_k = (n*_k.h*_k + u_free_k) / F_k, and substitutes it into the cost-to-go. Then
 *   lambda_S = (J^-T M z)_S (stationarity: M z = J^T lambda). O(n), about 60 flops per trailer.
 * - A is positive definite (J is square with a non-zero diagonal, M is positive definite), so the
 *   box LCP (a strictly convex QP in lambda) has exactly one solution: the dense solver's projected
 *   Gauss-Seidel finished by an exact solve on the sticking set and this solver both return it, up
 *   to round-off. It is found by block principal pivoting over the partitions, warm-started from
 *   the last substep's impulses: in steady sliding or sticking the first partition is already the
 *   solution (one O(n) solve; over 99 % of the LCPs in bench_slip.py), a change of several wheels
 *   at once takes a few more (2 to 8 from cold starts on random chains up to n = 50; rarely
 *   10-30 at n = 50 when the safeguard's single switches take over). So each fixed-point
 *   iteration costs O(n), and so does a substep; the onset forces use the same solver with M and
 *   J at the same headings.
 * Every wheel sliding is the cheapest partition (no sticking row): one backward and one forward
 * sweep with the factor of M. The end normals n*_k come from the start ones by the angle addition
 * (dt wt_k is small), not from a sine and cosine per iteration.
 */
#include <math.h>

#include "model.h"

/* ------------------------------------------------------------------------------------------------
 * The linear-time solver (see "Linear time" in the note above). Index k = 0..n-1 is trailer
 * k + 1 in the arrays of a Chain.
 */

#define PIVOT_BUDGET 3     /* block pivots without fewer infeasible wheels before single pivots */
#define PIVOT_ITERATIONS(n) (8 * (n) + 16) /* a cap; 1 partition in over 99 %, rarely 10-30 */
#define IMPULSE_TOLERANCE 1e-12 /* relative: a sticking impulse this far past its bound is on it */
#define SPEED_TOLERANCE 1e-12   /* relative to max |u_free|: a sliding wheel this slow is at rest */

/* The chain's data for one substep: M at the start headings (normals nx, ny), J at the end
   headings (normals sx, sy), and the Riccati factor of M. */
typedef struct {
    int n;
    double mass[MAX_TRAILERS];    /* m_k = mass + payload [kg] */
    double inertia[MAX_TRAILERS]; /* I_k [kg m^2] */
    double front[MAX_TRAILERS];   /* F_k [m] */
    double inv_front[MAX_TRAILERS]; /* 1 / F_k [1/m] */
    double link[MAX_TRAILERS];    /* D_k = F_k + R_k [m] */
    double nx[MAX_TRAILERS], ny[MAX_TRAILERS]; /* left normals where M is taken */
    double sx[MAX_TRAILERS], sy[MAX_TRAILERS]; /* left normals where J is taken */
    /* the factor of M: b_k / alpha_k, 1 / alpha_k, D_k n_k */
    double bx[MAX_TRAILERS], by[MAX_TRAILERS], inv_alpha[MAX_TRAILERS];
    double dnx[MAX_TRAILERS], dny[MAX_TRAILERS];
} Chain;

static void chain_init(const ModelData *m, Chain *ch) {
    int k;
    ch->n = m->n;
    for (k = 0; k < m->n; k++) {
        ch->mass[k] = m->mass[k + 1] + m->payload[k + 1];
        ch->inertia[k] = m->inertia[k + 1];
        ch->front[k] = m->front[k + 1];
        ch->inv_front[k] = 1.0 / m->front[k + 1];
        ch->link[k] = m->front[k + 1] + m->rear[k + 1];
    }
}

/* The normals n*_k = (-sin, cos)(th_end_k) where J is taken, from those of the start headings th
   (in ch->nx, ch->ny): the end headings differ by dt wt, a few milliradians, so the angle addition
   with a series for the small angle costs a fraction of a sine and cosine and agrees with them to
   a few units in the last place. */
static void chain_end_normals(Chain *ch, const double *th, const double *th_end) {
    int k;
    for (k = 0; k < ch->n; k++) {
        const double d = th_end[k] - th[k], d2 = d * d;
        if (fabs(d) < 1e-2) { /* Taylor series; the first omitted terms are below 1e-26 */
            const double sin_d =
                d + d * d2 * (-1.0 / 6.0 + d2 * (1.0 / 120.0 + d2 * (-1.0 / 5040.0
                                                                    + d2 * (1.0 / 362880.0))));
            const double cos_d =
                1.0 + d2 * (-0.5 + d2 * (1.0 / 24.0 + d2 * (-1.0 / 720.0 + d2 * (1.0 / 40320.0))));
            ch->sx[k] = ch->nx[k] * cos_d - ch->ny[k] * sin_d; /* -sin(th + d) */
            ch->sy[k] = ch->ny[k] * cos_d + ch->nx[k] * sin_d; /* cos(th + d) */
        } else {
            ch->sx[k] = -sin(th_end[k]);
            ch->sy[k] = cos(th_end[k]);
        }
    }
}

/* Riccati factor of M (the backward sweep of the note, P_k 2 x 2 symmetric), kept as
   b_k / alpha_k, 1 / alpha_k and D_k n_k. */
static void chain_factor(Chain *ch) {
    double pxx = 0.0, pxy = 0.0, pyy = 0.0;
    int k;
    for (k = ch->n - 1; k >= 0; k--) {
        const double nx = ch->nx[k], ny = ch->ny[k], d = ch->link[k];
        const double mf = ch->mass[k] * ch->front[k];
        const double pnx = pxx * nx + pxy * ny, pny = pxy * nx + pyy * ny;
        const double alpha = mf * ch->front[k] + ch->inertia[k] + d * d * (nx * pnx + ny * pny);
        const double bx = mf * nx + d * pnx, by = mf * ny + d * pny, ia = 1.0 / alpha;
        ch->bx[k] = bx * ia;
        ch->by[k] = by * ia;
        ch->inv_alpha[k] = ia;
        ch->dnx[k] = d * nx;
        ch->dny[k] = d * ny;
        pxx += ch->mass[k] - bx * ch->bx[k];
        pxy -= bx * ch->by[k];
        pyy += ch->mass[k] - by * ch->by[k];
    }
}

/* z = M^-1 f (z may be f): the backward sweep of the linear terms p_k, then the forward sweep
   z_k = (b_k.h_k + gamma_k) / alpha_k. */
static void chain_mass_solve(const Chain *ch, const double *f, double *z) {
    double gamma[MAX_TRAILERS], px = 0.0, py = 0.0, hx = 0.0, hy = 0.0;
    int k;
    for (k = ch->n - 1; k >= 0; k--) {
        const double g = f[k] + px * ch->dnx[k] + py * ch->dny[k];
        gamma[k] = g * ch->inv_alpha[k];
        px -= ch->bx[k] * g;
        py -= ch->by[k] * g;
    }
    for (k = 0; k < ch->n; k++) {
        const double zk = ch->bx[k] * hx + ch->by[k] * hy + gamma[k];
        z[k] = zk;
        hx -= ch->dnx[k] * zk;
        hy -= ch->dny[k] * zk;
    }
}

/* out = V_h.n*_k + J z (lateral wheel speeds with the yaw rates z and the robot's hitch moving
   at vh; vh = 0 for J z alone): a forward sweep. */
static void chain_wheel_speeds(const Chain *ch, const double *z, const double *vh,
                               double *out) {
    double hx = vh[0], hy = vh[1];
    int k;
    for (k = 0; k < ch->n; k++) {
        out[k] = ch->sx[k] * hx + ch->sy[k] * hy - ch->front[k] * z[k];
        hx -= ch->link[k] * z[k] * ch->sx[k];
        hy -= ch->link[k] * z[k] * ch->sy[k];
    }
}

/* f = J^T lam (generalized forces of the lateral wheel forces lam) over the wheels whose state is
   not 0 (the sliding ones): a backward sweep. */
static void chain_wheel_forces(const Chain *ch, const double *lam, const signed char *state,
                               double *f) {
    double tx = 0.0, ty = 0.0;
    int k;
    for (k = ch->n - 1; k >= 0; k--) {
        const double l = state[k] != 0 ? lam[k] : 0.0;
        f[k] = -(ch->front[k] * l + ch->link[k] * (ch->sx[k] * tx + ch->sy[k] * ty));
        tx += l * ch->sx[k];
        ty += l * ch->sy[k];
    }
}

/* The partition in which every wheel slides: z = M^-1 J^T lam and u = u_free + J z, with the
   sweeps of chain_wheel_forces and chain_mass_solve fused into one backward sweep and those of
   chain_mass_solve and chain_wheel_speeds into one forward sweep. */
static void slide_solve(const Chain *ch, const double *lam, const double *u_free, double *z,
                        double *u) {
    double gamma[MAX_TRAILERS], tx = 0.0, ty = 0.0, px = 0.0, py = 0.0;
    double hx = 0.0, hy = 0.0, sx = 0.0, sy = 0.0;
    int k;
    for (k = ch->n - 1; k >= 0; k--) {
        const double l = lam[k];
        const double g = -(ch->front[k] * l + ch->link[k] * (ch->sx[k] * tx + ch->sy[k] * ty))
                         + px * ch->dnx[k] + py * ch->dny[k];
        tx += l * ch->sx[k];
        ty += l * ch->sy[k];
        gamma[k] = g * ch->inv_alpha[k];
        px -= ch->bx[k] * g;
        py -= ch->by[k] * g;
    }
    for (k = 0; k < ch->n; k++) { /* h through the normals of M, (sx, sy) through those of J */
        const double zk = ch->bx[k] * hx + ch->by[k] * hy + gamma[k], dz = ch->link[k] * zk;
        z[k] = zk;
        u[k] = u_free[k] + ch->sx[k] * sx + ch->sy[k] * sy - ch->front[k] * zk;
        hx -= ch->dnx[k] * zk;
        hy -= ch->dny[k] * zk;
        sx -= dz * ch->sx[k];
        sy -= dz * ch->sy[k];
    }
}

/* The equality problem of a partition: wheels with state 0 stick, (J z)_k = -u_free_k, the others
   carry lam_k. z = M^-1 J^T lam with the sticking lam_k (written into lam) unknown, and
   u = u_free + J z. The 4-state sweep of the note: x = (h, h*), the front hitch velocity of
   trailer k through the normals n_k of M and n*_k of J; the cost-to-go x^T P x / 2 + p.x with
   P = [[A, B], [B^T, C]] (A, C symmetric 2 x 2) kept in scalars. With e = (n_k, n*_k) the step
   is x_{k+1} = x_k - D_k z_k e, and the cost of trailer k is m_k |h_k - F_k z_k n_k|^2 / 2 +
   I_k z_k^2 / 2 - f_k z_k: in z_k it is alpha z_k^2 / 2 + z_k (b.x + gam) + ... */
static void partition_solve(const Chain *ch, const signed char *state, const double *u_free,
                            double *lam, double *z, double *u) {
    const int n = ch->n;
    double beta[MAX_TRAILERS][4], gamma[MAX_TRAILERS]; /* sliding: z_k = -(beta.x) - gamma */
    double ax[MAX_TRAILERS], ay[MAX_TRAILERS];     /* axle velocities a_k through n_k */
    double f[MAX_TRAILERS] = {0.0}; /* zeroed because gcc cannot see that n values are set */
    double a00 = 0.0, a01 = 0.0, a11 = 0.0, b00 = 0.0, b01 = 0.0, b10 = 0.0, b11 = 0.0;
    double c00 = 0.0, c01 = 0.0, c11 = 0.0, p0 = 0.0, p1 = 0.0, p2 = 0.0, p3 = 0.0;
    double x0 = 0.0, x1 = 0.0, x2 = 0.0, x3 = 0.0;
    int k, sticking = 0;
    for (k = 0; k < n; k++) {
        sticking += (state[k] == 0);
    }
    if (sticking == 0) { /* every wheel slides: z = M^-1 J^T lam with the factor of M */
        slide_solve(ch, lam, u_free, z, u);
        return;
    }
    chain_wheel_forces(ch, lam, state, f);
    for (k = n - 1; k >= 0; k--) { /* backward: P_k, p_k from P_{k+1}, p_{k+1} */
        const double nx = ch->nx[k], ny = ch->ny[k], sx = ch->sx[k], sy = ch->sy[k];
        const double dk = ch->link[k], mk = ch->mass[k], mf = mk * ch->front[k];
        const double pe0 = a00 * nx + a01 * ny + b00 * sx + b01 * sy; /* P e */
        const double pe1 = a01 * nx + a11 * ny + b10 * sx + b11 * sy;
        const double pe2 = b00 * nx + b10 * ny + c00 * sx + c01 * sy;
        const double pe3 = b01 * nx + b11 * ny + c01 * sx + c11 * sy;
        const double alpha = mf * ch->front[k] + ch->inertia[k]
                             + dk * dk * (nx * pe0 + ny * pe1 + sx * pe2 + sy * pe3);
        const double bb0 = -dk * pe0 - mf * nx, bb1 = -dk * pe1 - mf * ny;
        const double bb2 = -dk * pe2, bb3 = -dk * pe3;
        const double gam = -dk * (p0 * nx + p1 * ny + p2 * sx + p3 * sy) - f[k];
        a00 += mk;
        a11 += mk;
        if (state[k] != 0) { /* sliding: z_k = -(b.x + gam) / alpha minimizes */
            const double ia = 1.0 / alpha;
            const double s0 = bb0 * ia, s1 = bb1 * ia, s2 = bb2 * ia, s3 = bb3 * ia;
            a00 -= bb0 * s0;
            a01 -= bb0 * s1;
            a11 -= bb1 * s1;
            b00 -= bb0 * s2;
            b01 -= bb0 * s3;
            b10 -= bb1 * s2;
            b11 -= bb1 * s3;
            c00 -= bb2 * s2;
            c01 -= bb2 * s3;
            c11 -= bb3 * s3;
            p0 -= s0 * gam;
            p1 -= s1 * gam;
            p2 -= s2 * gam;
            p3 -= s3 * gam;
            beta[k][0] = s0;
            beta[k][1] = s1;
            beta[k][2] = s2;
            beta[k][3] = s3;
            gamma[k] = gam * ia;
        } else { /* sticking: z_k = g.x + g0 with g = (0, 0, n*_k / F_k), g0 = u_free_k / F_k,
                    substituted: P += g b^T + b g^T + alpha g g^T, p += g0 b + (gam + alpha g0) g */
            const double g2 = sx * ch->inv_front[k], g3 = sy * ch->inv_front[k];
            const double g0 = u_free[k] * ch->inv_front[k], r = gam + alpha * g0;
            b00 += bb0 * g2;
            b01 += bb0 * g3;
            b10 += bb1 * g2;
            b11 += bb1 * g3;
            c00 += (2.0 * bb2 + alpha * g2) * g2;
            c01 += bb2 * g3 + bb3 * g2 + alpha * g2 * g3;
            c11 += (2.0 * bb3 + alpha * g3) * g3;
            p0 += g0 * bb0;
            p1 += g0 * bb1;
            p2 += g0 * bb2 + r * g2;
            p3 += g0 * bb3 + r * g3;
        }
    }
    for (k = 0; k < n; k++) { /* forward from x_1 = 0 */
        const double nx = ch->nx[k], ny = ch->ny[k], sx = ch->sx[k], sy = ch->sy[k];
        const double fk = ch->front[k], dk = ch->link[k];
        const double hs = sx * x2 + sy * x3; /* n*_k . h*_k */
        double zk, dz;
        if (state[k] != 0) {
            const double *bk = beta[k];
            zk = -(bk[0] * x0 + bk[1] * x1 + bk[2] * x2 + bk[3] * x3) - gamma[k];
        } else {
            zk = (hs + u_free[k]) * ch->inv_front[k];
        }
        z[k] = zk;
        u[k] = u_free[k] + hs - fk * zk;
        ax[k] = x0 - fk * zk * nx;
        ay[k] = x1 - fk * zk * ny;
        dz = dk * zk;
        x0 -= dz * nx;
        x1 -= dz * ny;
        x2 -= dz * sx;
        x3 -= dz * sy;
    }
    /* the sticking impulses: J^T lam = M z, by back substitution (J is triangular); the sweep
       carries s = sum_{i > k} m_i a_i (for M z) and t = sum_{i > k} lam_i n*_i */
    x0 = x1 = x2 = x3 = 0.0; /* s, t */
    for (k = n - 1; k >= 0; k--) {
        const double fk = ch->front[k], dk = ch->link[k], mk = ch->mass[k];
        if (state[k] == 0) {
            const double mz = ch->inertia[k] * z[k] - ch->nx[k] * (fk * mk * ax[k] + dk * x0)
                              - ch->ny[k] * (fk * mk * ay[k] + dk * x1);
            lam[k] = -(mz + dk * (ch->sx[k] * x2 + ch->sy[k] * x3)) * ch->inv_front[k];
        }
        x0 += mk * ax[k];
        x1 += mk * ay[k];
        x2 += lam[k] * ch->sx[k];
        x3 += lam[k] * ch->sy[k];
    }
}

/* The box LCP of the note: |lam_k| <= lim_k, u = u_free + J M^-1 J^T lam, u_k = 0 where
   |lam_k| < lim_k, lam_k opposing u_k where |lam_k| = lim_k. Block principal pivoting over the
   partitions (stick / slide at -lim / slide at +lim), started from the partition of lam (the
   warm start): every wheel whose partition is infeasible switches (a sticking impulse past its
   bound slides at that bound; a sliding wheel whose speed turned along its friction sticks);
   after PIVOT_BUDGET switches that did not lower the number of infeasible wheels, only the
   lowest-numbered one switches (Murty's rule, as in Judice & Pires' safeguard). Sets lam,
   z = M^-1 J^T lam and u; returns the number of partitions tried (PIVOT_ITERATIONS(n) + 1 if
   none was feasible). */
static int friction_impulses(const Chain *ch, const double *u_free, const double *lim,
                             double *lam, double *z, double *u) {
    const int n = ch->n;
    signed char state[MAX_TRAILERS] = {0}; /* zeroed: gcc cannot see that n are set */
    bool bad[MAX_TRAILERS];
    double speed = 0.0;
    int k, it, best = n + 1, budget = PIVOT_BUDGET;
    for (k = 0; k < n; k++) {
        speed = fabs(u_free[k]) > speed ? fabs(u_free[k]) : speed;
        if (lim[k] > 0.0 && fabs(lam[k]) < lim[k] * (1.0 - 1e-9)) {
            state[k] = 0;
        } else {
            state[k] = (signed char)(lam[k] < 0.0 ? -1 : 1);
        }
    }
    speed *= SPEED_TOLERANCE;
    for (it = 1; it <= PIVOT_ITERATIONS(n); it++) {
        int infeasible = 0, first = -1;
        bool all;
        for (k = 0; k < n; k++) {
            if (state[k] != 0) lam[k] = state[k] * lim[k];
        }
        partition_solve(ch, state, u_free, lam, z, u);
        for (k = 0; k < n; k++) {
            bad[k] = (state[k] == 0) ? fabs(lam[k]) > lim[k] * (1.0 + IMPULSE_TOLERANCE)
                                     : lim[k] > 0.0 && state[k] * u[k] > speed;
            if (bad[k]) {
                infeasible++;
                if (first < 0) first = k;
            }
        }
        if (infeasible == 0) {
            break;
        }
        if (infeasible < best) {
            best = infeasible;
            budget = PIVOT_BUDGET;
            all = true;
        } else {
            all = budget > 0;
            budget -= all;
        }
        for (k = 0; k < n; k++) {
            if (bad[k] && (all || k == first)) {
                state[k] = (signed char)(state[k] != 0 ? 0 : (lam[k] < 0.0 ? -1 : 1));
            }
        }
    }
    for (k = 0; k < n; k++) { /* within IMPULSE_TOLERANCE of the bound: on it */
        lam[k] = pt_clamp(lam[k], -lim[k], lim[k]);
    }
    if (it > PIVOT_ITERATIONS(n)) { /* no partition satisfied every wheel (never seen): the
                                       velocities follow the impulses, which stay in friction */
        slide_solve(ch, lam, u_free, z, u);
    }
    return it;
}

/* Generalized forces g of the note at headings (ct, st) (index 1..n) with yaw rates wt (1..n),
   into g[0..n-1]. S_kj = D_min(k,j) T_max(k,j) (k != j) with T_j = m_j F_j + D_j sum_{i > j} m_i,
   and sin(th_j - th_k) = e_j.n_k, so
     g_k = n_k.[T_k (a_h + sum_{j < k} D_j wt_j^2 e_j) + D_k sum_{j > k} T_j wt_j^2 e_j - L_nk push]
   with a prefix and a suffix sum: O(n). */
static void generalized_forces(const ModelData *m, const Chain *ch, const double *ct,
                               const double *st, const double *wt, const double *ah, double *g) {
    const int n = ch->n;
    double t_coef[MAX_TRAILERS], tail = 0.0, ex = 0.0, ey = 0.0;
    int k;
    for (k = n - 1; k >= 0; k--) { /* T_k and the suffix sum sum_{j > k} T_j wt_j^2 e_j */
        const double w2 = wt[k + 1] * wt[k + 1];
        t_coef[k] = ch->mass[k] * ch->front[k] + ch->link[k] * tail;
        tail += ch->mass[k];
        g[k] = -st[k + 1] * ex + ct[k + 1] * ey; /* n_k . suffix */
        ex += t_coef[k] * w2 * ct[k + 1];
        ey += t_coef[k] * w2 * st[k + 1];
    }
    ex = ah[0];
    ey = ah[1];
    for (k = 0; k < n; k++) {
        const double nx = -st[k + 1], ny = ct[k + 1], w2 = wt[k + 1] * wt[k + 1];
        const double l_nk = (k == n - 1) ? ch->front[k] : ch->link[k];
        g[k] = t_coef[k] * (nx * ex + ny * ey) + ch->link[k] * g[k]
               - l_nk * (nx * m->push_x + ny * m->push_y);
        ex += ch->link[k] * w2 * ct[k + 1];
        ey += ch->link[k] * w2 * st[k + 1];
    }
}

/* One substep of the dynamic regime; the friction impulses make the lateral wheel speeds
   consistent at the end of the substep (see the note at the top of slip.c). */
void slip_dynamic_step(ModelData *m, double dt) {
    const int n = m->n;
    Chain ch;
    double g[MAX_TRAILERS], lim[MAX_TRAILERS], lam[MAX_TRAILERS], w_free[MAX_TRAILERS];
    double w_new[MAX_TRAILERS], u_free[MAX_TRAILERS], z[MAX_TRAILERS], u[MAX_TRAILERS];
    double th[MAX_TRAILERS], vh[2], ah[2];
    /* zeroed because gcc cannot see that the loops fill the first n (ct, st: 1..n) */
    double th_end[MAX_TRAILERS] = {0.0}, ct[MAX_BODIES] = {0.0}, st[MAX_BODIES] = {0.0};
    double *q = m->q;
    int i, k, it;
    bool all_stick = true;

    chain_init(m, &ch);
    robot_hitch(m, q, vh, ah);
    for (k = 1; k <= n; k++) {
        th[k - 1] = q[IX_THETA + k];
        ct[k] = cos(th[k - 1]);
        st[k] = sin(th[k - 1]);
        ch.nx[k - 1] = -st[k];
        ch.ny[k - 1] = ct[k];
    }
    chain_factor(&ch);
    generalized_forces(m, &ch, ct, st, m->wt, ah, g);
    for (k = 0; k < n; k++) g[k] *= dt;
    chain_mass_solve(&ch, g, w_free);
    for (k = 0; k < n; k++) {
        w_free[k] += m->wt[k + 1];
        th_end[k] = th[k] + dt * w_free[k]; /* predicted end headings */
        w_new[k] = w_free[k];
        u[k] = 0.0;
    }
    for (i = 0; i < n; i++) {
        lim[i] = m->F_lat_max[i + 1] * dt;
        lam[i] = pt_clamp(m->f_dyn[i + 1] * dt, -lim[i], lim[i]); /* warm start */
    }

    robot_rk4(m, q, dt); /* the robot moves on: the wheel speeds use its velocity at t + dt */
    robot_hitch(m, q, vh, ah);
    for (it = 0; it < CONFIG_ITERATIONS; it++) {
        double change = 0.0;
        chain_end_normals(&ch, th, th_end);
        chain_wheel_speeds(&ch, w_free, vh, u_free);
        friction_impulses(&ch, u_free, lim, lam, z, u);
        for (k = 0; k < n; k++) {
            double th_k;
            w_new[k] = w_free[k] + z[k];
            th_k = th[k] + dt * w_new[k];
            const double moved = fabs(th_k - th_end[k]);
            change = moved > change ? moved : change;
            th_end[k] = th_k;
        }
        if (change <= CONFIG_TOLERANCE) {
            break;
        }
    }
    for (k = 0; k < n; k++) {
        m->alpha_dyn[k + 1] = (w_new[k] - m->wt[k + 1]) / dt;
        m->wt[k + 1] = w_new[k];
        q[IX_THETA + k + 1] = th_end[k];
    }
    for (i = 0; i < n; i++) {
        m->f_dyn[i + 1] = lam[i] / dt;
        if (fabs(u[i]) > STICK_SPEED || fabs(lam[i]) >= lim[i] * (1.0 - 1e-9)) {
            all_stick = false;
        }
    }
    if (all_stick && slip_wheels_roll(m, q)) {
        m->dynamic = false;
    }
}

/* Velocity outputs from the trailer yaw rates wt (index 1..n) at the current state, with the
   sums over the links ahead carried along the chain (O(n)). */
static void write_velocities(ModelData *m, const double *wt) {
    const int n = m->n;
    const double *q = m->q;
    double vh[2], ah[2], sum_x = 0.0, sum_y = 0.0; /* sum_{k < i} D_k wt_k (sin, cos)(th_k) */
    int i;
    robot_hitch(m, q, vh, ah);
    m->v[0] = q[IX_V0];
    m->w[0] = q[IX_W0];
    for (i = 1; i <= n; i++) {
        const double th_i = q[IX_THETA + i], ex = cos(th_i), ey = sin(th_i);
        const double d = m->front[i] + m->rear[i];
        const double vx = vh[0] + sum_x + m->front[i] * wt[i] * ey; /* - sum L_ik wt_k n_k */
        const double vy = vh[1] - sum_y - m->front[i] * wt[i] * ex;
        m->v[i] = vx * ex + vy * ey;
        m->w[i] = wt[i];
        m->slide_speed[i] = -vx * ey + vy * ex;
        sum_x += d * wt[i] * ey;
        sum_y += d * wt[i] * ex;
    }
}

/* Force outputs from yaw rates wt, yaw accelerations alpha and lateral wheel forces f (index
   1..n) at the current state: F_lat and, from the axle accelerations, the hitch forces (O(n)). */
static void write_forces(ModelData *m, const double *wt, const double *alpha, const double *f) {
    const int n = m->n;
    const double *q = m->q;
    double vh[2], ah[2], next_fx = 0.0, next_fy = 0.0, sum_x = 0.0, sum_y = 0.0;
    double ax[MAX_BODIES], ay[MAX_BODIES];
    int i;
    robot_hitch(m, q, vh, ah);
    /* a_i = a_h - sum_{k <= i} L_ik (alpha_k n_k - wt_k^2 e_k) */
    for (i = 1; i <= n; i++) {
        const double th_i = q[IX_THETA + i], ex = cos(th_i), ey = sin(th_i);
        const double cx = alpha[i] * ey + wt[i] * wt[i] * ex; /* -(alpha n - w^2 e) */
        const double cy = -alpha[i] * ex + wt[i] * wt[i] * ey;
        ax[i] = ah[0] + sum_x + m->front[i] * cx;
        ay[i] = ah[1] + sum_y + m->front[i] * cy;
        sum_x += (m->front[i] + m->rear[i]) * cx;
        sum_y += (m->front[i] + m->rear[i]) * cy;
        m->F_lat[i] = f[i];
    }
    /* hitch forces from trailer n down: f_i = f_{i+1} + m_i a_i - F_d,i n_i - push (i = n) */
    for (i = n; i >= 1; i--) {
        const double th_i = q[IX_THETA + i];
        const double mi = m->mass[i] + m->payload[i];
        const double nx = -sin(th_i), ny = cos(th_i);
        m->hitch_fx[i] = next_fx + mi * ax[i] - m->F_lat[i] * nx - (i == n ? m->push_x : 0.0);
        m->hitch_fy[i] = next_fy + mi * ay[i] - m->F_lat[i] * ny - (i == n ? m->push_y : 0.0);
        next_fx = m->hitch_fx[i];
        next_fy = m->hitch_fy[i];
    }
}

void slip_outputs(ModelData *m) {
    write_velocities(m, m->wt);
    write_forces(m, m->wt, m->alpha_dyn, m->f_dyn);
}

void slip_onset_outputs(ModelData *m) {
    const int n = m->n;
    Chain ch;
    double c[MAX_BODIES], s[MAX_BODIES], v[MAX_BODIES], wt[MAX_BODIES], alpha[MAX_BODIES];
    double f[MAX_BODIES], g[MAX_TRAILERS], lam[MAX_TRAILERS], z[MAX_TRAILERS];
    double u[MAX_TRAILERS], th[MAX_TRAILERS];
    /* index 1..n (0..n-1) used; zeroed because gcc cannot see that the loops fill them */
    double ct[MAX_BODIES] = {0.0}, st[MAX_BODIES] = {0.0}, jg[MAX_TRAILERS] = {0.0};
    double r[MAX_TRAILERS] = {0.0}, lim[MAX_TRAILERS] = {0.0};
    double vh[2], ah[2], sum_x = 0.0, sum_y = 0.0, sum2_x = 0.0, sum2_y = 0.0;
    const double no_motion[2] = {0.0, 0.0}; /* J g alone */
    const double *q = m->q;
    int i, k;
    chain_velocities(m, q, c, s, v, wt); /* rolling: the kinematic yaw rates, u = 0 */
    robot_hitch(m, q, vh, ah);
    chain_init(m, &ch);
    for (k = 1; k <= n; k++) {
        th[k - 1] = q[IX_THETA + k];
        ct[k] = cos(th[k - 1]);
        st[k] = sin(th[k - 1]);
        ch.nx[k - 1] = ch.sx[k - 1] = -st[k]; /* M and J at the same headings */
        ch.ny[k - 1] = ch.sy[k - 1] = ct[k];
    }
    chain_factor(&ch);
    generalized_forces(m, &ch, ct, st, wt, ah, g);
    chain_mass_solve(&ch, g, g); /* g <- M^-1 g */
    chain_wheel_speeds(&ch, g, no_motion, jg);
    /* r = J M^-1 g + c,
       c_i = a_h.n_i - wt_i V_h.e_i + n_i . sum_{k < i} D_k (wt_k - wt_i) wt_k e_k */
    for (i = 1; i <= n; i++) {
        const double nx = -st[i], ny = ct[i];
        r[i - 1] = ah[1] * ct[i] - ah[0] * st[i] - wt[i] * (vh[0] * ct[i] + vh[1] * st[i])
                   + nx * (sum2_x - wt[i] * sum_x) + ny * (sum2_y - wt[i] * sum_y) + jg[i - 1];
        lim[i - 1] = m->F_lat_max[i];
        lam[i - 1] = pt_clamp(m->F_lat[i], -lim[i - 1], lim[i - 1]); /* warm start */
        sum_x += (m->front[i] + m->rear[i]) * wt[i] * ct[i];
        sum_y += (m->front[i] + m->rear[i]) * wt[i] * st[i];
        sum2_x += (m->front[i] + m->rear[i]) * wt[i] * wt[i] * ct[i];
        sum2_y += (m->front[i] + m->rear[i]) * wt[i] * wt[i] * st[i];
    }
    friction_impulses(&ch, r, lim, lam, z, u);
    alpha[0] = f[0] = 0.0;
    for (k = 0; k < n; k++) {
        alpha[k + 1] = g[k] + z[k];
        f[k + 1] = lam[k];
    }
    write_forces(m, wt, alpha, f); /* the velocities stay those of rolling */
}

