/*
 * slip_mode 1: trailer wheels that slide sideways when rolling would need more lateral force than
 * Coulomb friction gives (assumption C3), mu_i (m_i + payload_i) g.
 *
 * Formulation: an exact stick/slip treatment by velocity-level time stepping (Moreau-Jean).
 * - While every wheel can roll (the force rolling needs is within friction at the start and at
 *   the end of the substep), the substep is the kinematic RK4 step of slip_mode 0: mode 1 then
 *   reproduces mode 0 exactly. A rolling substep that ends where rolling needs more than friction
 *   is not taken: the wheels slide from its start instead.
 * - Otherwise the trailer headings th_1..th_n become dynamic with yaw rates wt_k as states (the
 *   robot stays velocity-controlled, assumption C4). With the hitch constraints eliminated, the
 *   Lagrange equations in th are  M(th) alpha = g(th, wt, robot) + J_u^T F_d,  where
 *     L_ik = F_k + R_k (k < i), F_i (k = i), 0 (k > i)   (d P_i / d th_k = -L_ik n_k)
 *     M_kj = sum_{i >= max(k,j)} m_i L_ik L_ij cos(th_k - th_j) + I_k delta_kj
 *     g_k  = sum_{i >= k} m_i L_ik [n_k.a_h + sum_{j <= i} L_ij wt_j^2 sin(th_j - th_k)]
 *            - L_nk n_k.push
 *     u_i  = V_h.n_i + sum_k J_ik wt_k,  J_ik = -L_ik cos(th_k - th_i)   (lateral wheel speed)
 *   with a_h, V_h the acceleration and velocity of the robot's rear hitch. Each substep solves
 *   for friction impulses lambda_i = F_d,i dt with |lambda_i| <= mu_i (m_i + payload_i) g dt and
 *   lambda_i opposing u_i, or u_i = 0 for a sticking wheel (a box-constrained LCP on
 *   A = J M^-1 J^T), then wt+ = wt_free + M^-1 J^T lambda and th+ = th + dt wt+.
 *
 * Where the constraint is imposed. Outputs (and the next substep) see the end of the substep,
 * (th+, wt+, V_h(t + dt)). Imposing u = 0 with J and n_i at the start headings th leaves
 *   u_i(th+, wt+) = dt (du_i/dth) wt+ = dt [-wt_i V_h.e_i + sum_k L_ik sin(th_k - th_i)(wt_k - wt_i) wt_k]
 * at the end: a sticking wheel drifts sideways at O(dt) (2.4e-5 m/s for 0.5 ms substeps). So J and
 * b = V_h.n are taken at the end headings th+ = th + dt wt+, which depend on the unknown wt+: a
 * fixed point th* -> (LCP with J(th*)) -> wt+ -> th + dt wt+, started from th + dt wt_free. Its
 * contraction factor is about dt (|V_h| + L |wt|) / L << 1 (2 or 3 iterations reach
 * |dth| < CONFIG_TOLERANCE), and then |u(th+, wt+)| <= (|V_h| + L |wt|) CONFIG_TOLERANCE for a
 * sticking wheel, provided the LCP itself is exact on it: each candidate partition is solved
 * exactly (u_S = 0 with the sliding impulses lambda_L at their bounds), see "Linear time".
 * Friction stays implicit: |lambda_i| <= limit dt, so |F_d,i| never exceeds the limit. When every
 * wheel sticks and rolling needs no more than friction at the new state, the state returns to the
 * kinematic regime.
 *
 * Onset of sliding (outputs only). Between substeps the inputs can change (direct feedthrough):
 * in the kinematic regime the force rolling would need may then exceed friction before any time
 * has passed. The outputs then report the Coulomb forces of that instant, from the same
 * equations at the acceleration level: with u = 0 and
 *   du_i/dt = a_h.n_i - wt_i V_h.e_i + sum_k L_ik sin(th_k - th_i)(wt_k - wt_i) wt_k + (J alpha)_i
 * and alpha = M^-1 (g + J^T F), du/dt = A F + r with r = J M^-1 g + c (c: the terms before J alpha).
 * The same box LCP (bounds mu (m + payload) g, du_i/dt = 0 while |F_i| is below them) gives F;
 * if every wheel can roll it is the Newton-Euler force of forces.c.
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
 * The dense solver (O(n^3) per substep) stays in this file under PT_SLIP_DENSE_REFERENCE, as the
 * independent reference the tests compare against (tests/test_fmu_slip_reference.py builds it).
 */
#include <math.h>
#include <string.h>

#include "model.h"

#define STICK_SPEED 1e-7 /* |u| below this counts as rolling when leaving the dynamic regime */
#define CONFIG_ITERATIONS 8       /* fixed-point iterations on the end-of-substep headings */
#define CONFIG_TOLERANCE 1e-12    /* [rad] end headings converged: |u| error <= speed * 1e-12 */

/* Robot rear hitch: velocity vh and acceleration ah (world) at state q. */
static void robot_hitch(const ModelData *m, const double *q, double *vh, double *ah) {
    const double th = q[IX_THETA], v0 = q[IX_V0], w0 = q[IX_W0], r = m->rear[0];
    const double ex = cos(th), ey = sin(th), nx = -ey, ny = ex;
    double dv0, dw0;
    robot_accelerations(m, q, &dv0, &dw0);
    vh[0] = v0 * ex - r * w0 * nx;
    vh[1] = v0 * ey - r * w0 * ny;
    /* a0 = dv0 e0 + v0 w0 n0;  a_h = a0 - R0 (dw0 n0 - w0^2 e0) */
    ah[0] = dv0 * ex + v0 * w0 * nx - r * (dw0 * nx - w0 * w0 * ex);
    ah[1] = dv0 * ey + v0 * w0 * ny - r * (dw0 * ny - w0 * w0 * ey);
}

/* RK4 of the robot alone (its motion does not depend on the trailers). */
static void robot_rk4(const ModelData *m, double *q, double dt) {
    double k[4][5], tmp[MAX_STATE];
    const int idx[5] = {IX_X0, IX_Y0, IX_THETA, IX_V0, IX_W0};
    const double weight[4] = {0.0, 0.5, 0.5, 1.0};
    int stage, j;
    memcpy(tmp, q, sizeof(tmp));
    for (stage = 0; stage < 4; stage++) {
        for (j = 0; j < 5 && stage > 0; j++) {
            tmp[idx[j]] = q[idx[j]] + weight[stage] * dt * k[stage - 1][j];
        }
        k[stage][0] = tmp[IX_V0] * cos(tmp[IX_THETA]);
        k[stage][1] = tmp[IX_V0] * sin(tmp[IX_THETA]);
        k[stage][2] = tmp[IX_W0];
        robot_accelerations(m, tmp, &k[stage][3], &k[stage][4]);
    }
    for (j = 0; j < 5; j++) {
        q[idx[j]] += dt / 6.0 * (k[0][j] + 2.0 * k[1][j] + 2.0 * k[2][j] + k[3][j]);
    }
}

bool slip_wheels_roll(const ModelData *m, const double *q) {
    double c[MAX_BODIES], s[MAX_BODIES], v[MAX_BODIES], w[MAX_BODIES], dv[MAX_BODIES];
    double dw[MAX_BODIES], f[MAX_BODIES], hx[MAX_BODIES], hy[MAX_BODIES];
    double dv0, dw0;
    int i;
    chain_velocities(m, q, c, s, v, w);
    robot_accelerations(m, q, &dv0, &dw0);
    chain_accelerations(m, c, s, v, w, dv0, dw0, dv, dw);
    lateral_forces(m, q, v, w, dv, dw, f, hx, hy);
    for (i = 1; i <= m->n; i++) {
        if (fabs(f[i]) > m->F_lat_max[i]) {
            return false;
        }
    }
    return true;
}

static void enter_dynamic(ModelData *m) {
    double c[MAX_BODIES], s[MAX_BODIES], v[MAX_BODIES], w[MAX_BODIES];
    int i;
    chain_velocities(m, m->q, c, s, v, w);
    for (i = 1; i <= m->n; i++) {
        m->wt[i] = w[i];
        m->f_dyn[i] = 0.0;
        m->alpha_dyn[i] = 0.0;
    }
    m->dynamic = true;
}


#ifdef PT_SLIP_DENSE_REFERENCE
/* ------------------------------------------------------------------------------------------------
 * The dense solver, O(n^3) per substep: the reference for the tests, not built into FMUs.
 */

#define PGS_ITERATIONS 200

/* L_ik of the note above, with trailer indices 1..n. */
static double link_sum(const ModelData *m, int i, int k) {
    if (k > i) {
        return 0.0;
    }
    return (k < i) ? m->front[k] + m->rear[k] : m->front[k];
}

/* Cholesky factorization of the SPD n x n matrix a (row-major, in place, lower triangle). */
static void cholesky(double *a, int n) {
    int i, j, k;
    for (j = 0; j < n; j++) {
        double d = a[j * n + j];
        for (k = 0; k < j; k++) d -= a[j * n + k] * a[j * n + k];
        d = sqrt(d > 0.0 ? d : 1e-300);
        a[j * n + j] = d;
        for (i = j + 1; i < n; i++) {
            double s = a[i * n + j];
            for (k = 0; k < j; k++) s -= a[i * n + k] * a[j * n + k];
            a[i * n + j] = s / d;
        }
    }
}

static void cholesky_solve(const double *l, int n, double *b) {
    int i, k;
    for (i = 0; i < n; i++) {
        double s = b[i];
        for (k = 0; k < i; k++) s -= l[i * n + k] * b[k];
        b[i] = s / l[i * n + i];
    }
    for (i = n - 1; i >= 0; i--) {
        double s = b[i];
        for (k = i + 1; k < n; k++) s -= l[k * n + i] * b[k];
        b[i] = s / l[i * n + i];
    }
}


/* Jacobian J (n x n, row i-1 = wheel i) of the lateral wheel speeds and their offset b, with
   ct, st the cosines and sines of the trailer headings (index 1..n). */
static void wheel_speed_map(const ModelData *m, const double *ct, const double *st,
                            const double *vh, double *jac, double *b) {
    const int n = m->n;
    int i, k;
    for (i = 1; i <= n; i++) {
        b[i - 1] = -vh[0] * st[i] + vh[1] * ct[i];
        for (k = 1; k <= n; k++) { /* cos(th_k - th_i) */
            jac[(i - 1) * n + (k - 1)] = -link_sum(m, i, k) * (ct[k] * ct[i] + st[k] * st[i]);
        }
    }
}

/* Trailer dynamics at headings (ct, st) with yaw rates wt: the Cholesky factor of M (in place of
   mass) and g (into g). O(n^2) with S_kj = sum_{i >= max(k,j)} m_i L_ik L_ij: for k < j,
   S_kj = (F_k + R_k) T_j with T_j = m_j F_j + (F_j + R_j) sum_{i > j} m_i, and
   S_jj = m_j F_j^2 + (F_j + R_j)^2 sum_{i > j} m_i. Then M_kj = S_kj cos(th_k - th_j) + I_k delta_kj
   and g_k = T_k n_k.a_h + sum_j S_kj wt_j^2 sin(th_j - th_k) - L_nk n_k.push. */
static void trailer_dynamics(const ModelData *m, const double *ct, const double *st,
                             const double *wt, const double *ah, double *mass, double *g) {
    const int n = m->n;
    double s_mat[MAX_TRAILERS * MAX_TRAILERS], t_coef[MAX_TRAILERS], tail = 0.0; /* tail: sum of the masses behind trailer k */
    int j, k;
    for (k = n; k >= 1; k--) {
        const double mk = m->mass[k] + m->payload[k];
        const double fr = m->front[k] + m->rear[k];
        t_coef[k - 1] = mk * m->front[k] + fr * tail;
        s_mat[(k - 1) * n + (k - 1)] = mk * m->front[k] * m->front[k] + fr * fr * tail;
        tail += mk;
    }
    for (k = 1; k <= n; k++) {
        for (j = k + 1; j <= n; j++) {
            const double skj = (m->front[k] + m->rear[k]) * t_coef[j - 1];
            s_mat[(k - 1) * n + (j - 1)] = skj;
            s_mat[(j - 1) * n + (k - 1)] = skj;
        }
    }
    for (k = 1; k <= n; k++) {
        const double nkx = -st[k], nky = ct[k];
        double gk = t_coef[k - 1] * (nkx * ah[0] + nky * ah[1]);
        for (j = 1; j <= n; j++) {
            const double skj = s_mat[(k - 1) * n + (j - 1)];
            const double cos_d = ct[j] * ct[k] + st[j] * st[k]; /* cos(th_j - th_k) */
            const double sin_d = st[j] * ct[k] - ct[j] * st[k]; /* sin(th_j - th_k) */
            mass[(k - 1) * n + (j - 1)] = skj * cos_d + (j == k ? m->inertia[k] : 0.0);
            gk += skj * wt[j] * wt[j] * sin_d;
        }
        gk -= link_sum(m, n, k) * (nkx * m->push_x + nky * m->push_y);
        g[k - 1] = gk;
    }
    cholesky(mass, n);
}

/* M^-1 J^T (column by column, from the Cholesky factor chol) and A = J M^-1 J^T. J is lower
   triangular (L_ik = 0 for k > i) and A symmetric: A_ij = sum_{k <= i} J_ik (M^-1 J^T)_kj, j <= i. */
static void coupling(int n, const double *chol, const double *jac, double *minv_jt, double *a) {
    int i, j, k;
    for (i = 0; i < n; i++) {
        double col[MAX_TRAILERS];
        for (k = 0; k < n; k++) col[k] = jac[i * n + k];
        cholesky_solve(chol, n, col);
        for (k = 0; k < n; k++) minv_jt[k * n + i] = col[k];
    }
    for (i = 0; i < n; i++) {
        for (j = 0; j <= i; j++) {
            double sum = 0.0;
            for (k = 0; k <= i; k++) sum += jac[i * n + k] * minv_jt[k * n + j];
            a[i * n + j] = sum;
            a[j * n + i] = sum;
        }
    }
}

/* The exact solution on the sticking set S (|lam_i| inside its bound): A_SS lam_S =
   -(u_free + A_SL lam_L)_S. Kept only if it stays within the bounds. */
static void solve_sticking_set(int n, const double *a, const double *u_free, const double *lim,
                               double *lam) {
    double sub[MAX_TRAILERS * MAX_TRAILERS], rhs[MAX_TRAILERS];
    int idx[MAX_TRAILERS] = {0}, ns = 0, r, c, j; /* zeroed: gcc cannot see ns <= n */
    bool in_set[MAX_TRAILERS];
    for (j = 0; j < n; j++) {
        in_set[j] = fabs(lam[j]) < lim[j] * (1.0 - 1e-9);
        if (in_set[j]) idx[ns++] = j;
    }
    if (ns == 0) {
        return;
    }
    for (r = 0; r < ns; r++) {
        const int i = idx[r];
        rhs[r] = -u_free[i];
        for (j = 0; j < n; j++) {
            if (!in_set[j]) rhs[r] -= a[i * n + j] * lam[j];
        }
        for (c = 0; c < ns; c++) sub[r * ns + c] = a[i * n + idx[c]];
    }
    cholesky(sub, ns);
    cholesky_solve(sub, ns, rhs);
    for (r = 0; r < ns; r++) {
        if (!(fabs(rhs[r]) <= lim[idx[r]])) {
            return; /* the sticking set was not the final one: keep the iterative solution */
        }
    }
    for (r = 0; r < ns; r++) lam[idx[r]] = rhs[r];
}

/* Box-constrained LCP: |lam_i| <= lim_i, u = u_free + A lam with u_i = 0 where |lam_i| < lim_i
   and lam_i opposing u_i where |lam_i| = lim_i. Projected Gauss-Seidel from the warm start in
   lam, then the exact solve on the sticking set. */
static void solve_friction(int n, const double *a, const double *u_free, const double *lim,
                           double *lam) {
    double scale = 0.0;
    int i, j, it;
    for (i = 0; i < n; i++) scale = fmax(scale, lim[i]);
    for (it = 0; it < PGS_ITERATIONS; it++) {
        double change = 0.0;
        for (i = 0; i < n; i++) {
            double u = u_free[i], updated;
            for (j = 0; j < n; j++) u += a[i * n + j] * lam[j];
            updated = pt_clamp(lam[i] - u / a[i * n + i], -lim[i], lim[i]);
            change = fmax(change, fabs(updated - lam[i]));
            lam[i] = updated;
        }
        if (change <= 1e-10 * scale) { /* relative to the largest bound */
            break;
        }
    }
    solve_sticking_set(n, a, u_free, lim, lam);
}

/* One substep of the dynamic regime; the friction impulses make the lateral wheel speeds
   consistent at the end of the substep (see the note at the top). */
static void dynamic_step(ModelData *m, double dt) {
    enum { nn = MAX_TRAILERS * MAX_TRAILERS };
    const int n = m->n;
    double mass[nn], g[MAX_TRAILERS], jac[nn], minv_jt[nn], a[nn], b[MAX_TRAILERS];
    double lim[MAX_TRAILERS], lam[MAX_TRAILERS], w_free[MAX_TRAILERS], w_new[MAX_TRAILERS];
    double u_free[MAX_TRAILERS], vh[2], ah[2];
    /* zeroed because gcc cannot see that the loops fill the first n (ct, st: 1..n) */
    double th_end[MAX_TRAILERS] = {0.0}, ct[MAX_BODIES] = {0.0}, st[MAX_BODIES] = {0.0};
    double *q = m->q;
    int i, k, it;
    bool all_stick = true;

    robot_hitch(m, q, vh, ah);
    for (k = 1; k <= n; k++) {
        ct[k] = cos(q[IX_THETA + k]);
        st[k] = sin(q[IX_THETA + k]);
    }
    trailer_dynamics(m, ct, st, m->wt, ah, mass, g);
    for (k = 0; k < n; k++) w_free[k] = g[k] * dt;
    cholesky_solve(mass, n, w_free);
    for (k = 0; k < n; k++) {
        w_free[k] += m->wt[k + 1];
        th_end[k] = q[IX_THETA + k + 1] + dt * w_free[k]; /* predicted end headings */
        w_new[k] = w_free[k];
    }
    for (i = 0; i < n; i++) {
        lim[i] = m->F_lat_max[i + 1] * dt;
        lam[i] = pt_clamp(m->f_dyn[i + 1] * dt, -lim[i], lim[i]); /* warm start */
    }

    robot_rk4(m, q, dt); /* the robot moves on: the wheel speeds use its velocity at t + dt */
    robot_hitch(m, q, vh, ah);
    for (it = 0; it < CONFIG_ITERATIONS; it++) {
        double change = 0.0;
        for (k = 1; k <= n; k++) {
            ct[k] = cos(th_end[k - 1]);
            st[k] = sin(th_end[k - 1]);
        }
        wheel_speed_map(m, ct, st, vh, jac, b);
        for (i = 0; i < n; i++) {
            double u = b[i];
            for (k = 0; k < n; k++) u += jac[i * n + k] * w_free[k];
            u_free[i] = u;
        }
        coupling(n, mass, jac, minv_jt, a);
        solve_friction(n, a, u_free, lim, lam);
        for (k = 0; k < n; k++) {
            double th;
            w_new[k] = w_free[k];
            for (i = 0; i < n; i++) w_new[k] += minv_jt[k * n + i] * lam[i];
            th = q[IX_THETA + k + 1] + dt * w_new[k];
            change = fmax(change, fabs(th - th_end[k]));
            th_end[k] = th;
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
        double u = b[i];
        for (k = 0; k < n; k++) u += jac[i * n + k] * w_new[k];
        m->f_dyn[i + 1] = lam[i] / dt;
        if (fabs(u) > STICK_SPEED || fabs(lam[i]) >= lim[i] * (1.0 - 1e-9)) {
            all_stick = false;
        }
    }
    if (all_stick && slip_wheels_roll(m, q)) {
        m->dynamic = false;
    }
}



/* Velocity outputs from the trailer yaw rates wt (index 1..n) at the current state. */
static void write_velocities(ModelData *m, const double *wt) {
    const int n = m->n;
    const double *q = m->q;
    double vh[2], ah[2];
    int i, k;
    robot_hitch(m, q, vh, ah);
    m->v[0] = q[IX_V0];
    m->w[0] = q[IX_W0];
    for (i = 1; i <= n; i++) {
        const double th_i = q[IX_THETA + i];
        const double ex = cos(th_i), ey = sin(th_i);
        double vx = vh[0], vy = vh[1];
        for (k = 1; k <= i; k++) {
            const double th_k = q[IX_THETA + k], l = link_sum(m, i, k);
            vx += l * wt[k] * sin(th_k);  /* - L_ik wt_k n_k */
            vy -= l * wt[k] * cos(th_k);
        }
        m->v[i] = vx * ex + vy * ey;
        m->w[i] = wt[i];
        m->slide_speed[i] = -vx * ey + vy * ex;
    }
}

/* Force outputs from yaw rates wt, yaw accelerations alpha and lateral wheel forces f (index
   1..n) at the current state: F_lat and, from the axle accelerations, the hitch forces. */
static void write_forces(ModelData *m, const double *wt, const double *alpha, const double *f) {
    const int n = m->n;
    const double *q = m->q;
    double vh[2], ah[2], next_fx = 0.0, next_fy = 0.0;
    double ax[MAX_BODIES], ay[MAX_BODIES];
    int i, k;
    robot_hitch(m, q, vh, ah);
    for (i = 1; i <= n; i++) {
        ax[i] = ah[0];
        ay[i] = ah[1];
        for (k = 1; k <= i; k++) {
            const double th_k = q[IX_THETA + k], l = link_sum(m, i, k);
            const double nkx = -sin(th_k), nky = cos(th_k);
            const double w = wt[k], al = alpha[k];
            ax[i] -= l * (al * nkx - w * w * cos(th_k));
            ay[i] -= l * (al * nky - w * w * sin(th_k));
        }
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
    enum { nn = MAX_TRAILERS * MAX_TRAILERS };
    const int n = m->n;
    double c[MAX_BODIES], s[MAX_BODIES], v[MAX_BODIES], wt[MAX_BODIES], alpha[MAX_BODIES];
    double f[MAX_BODIES], mass[nn], g[MAX_TRAILERS], jac[nn], minv_jt[nn], a[nn];
    double b[MAX_TRAILERS], lam[MAX_TRAILERS];
    /* index 1..n (0..n-1) used; zeroed because gcc cannot see that the loops fill them */
    double ct[MAX_BODIES] = {0.0}, st[MAX_BODIES] = {0.0};
    double r[MAX_TRAILERS] = {0.0}, lim[MAX_TRAILERS] = {0.0};
    double vh[2], ah[2];
    const double *q = m->q;
    int i, k;
    chain_velocities(m, q, c, s, v, wt); /* rolling: the kinematic yaw rates, u = 0 */
    robot_hitch(m, q, vh, ah);
    for (k = 1; k <= n; k++) {
        ct[k] = cos(q[IX_THETA + k]);
        st[k] = sin(q[IX_THETA + k]);
    }
    trailer_dynamics(m, ct, st, wt, ah, mass, g);
    wheel_speed_map(m, ct, st, vh, jac, b);
    coupling(n, mass, jac, minv_jt, a);
    cholesky_solve(mass, n, g); /* g <- M^-1 g */
    for (i = 1; i <= n; i++) { /* r = J M^-1 g + c */
        double ri = ah[1] * ct[i] - ah[0] * st[i] - wt[i] * (vh[0] * ct[i] + vh[1] * st[i]);
        for (k = 1; k <= i; k++) {
            const double sin_ki = st[k] * ct[i] - ct[k] * st[i]; /* sin(th_k - th_i) */
            ri += link_sum(m, i, k) * sin_ki * (wt[k] - wt[i]) * wt[k];
        }
        for (k = 0; k < n; k++) ri += jac[(i - 1) * n + k] * g[k];
        r[i - 1] = ri;
        lim[i - 1] = m->F_lat_max[i];
        lam[i - 1] = pt_clamp(m->F_lat[i], -lim[i - 1], lim[i - 1]); /* warm start */
    }
    solve_friction(n, a, r, lim, lam);
    alpha[0] = f[0] = 0.0;
    for (k = 0; k < n; k++) {
        alpha[k + 1] = g[k];
        for (i = 0; i < n; i++) alpha[k + 1] += minv_jt[k * n + i] * lam[i];
        f[k + 1] = lam[k];
    }
    write_forces(m, wt, alpha, f); /* the velocities stay those of rolling */
}


#else /* the linear-time solver */

/* ------------------------------------------------------------------------------------------------
 * The linear-time solver (see "Linear time" in the note at the top). Index k = 0..n-1 is trailer
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
   consistent at the end of the substep (see the note at the top). */
static void dynamic_step(ModelData *m, double dt) {
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

#endif /* PT_SLIP_DENSE_REFERENCE */

double slip_advance(ModelData *m, double t_left, bool *rolls) {
    double dt;
    if (!m->dynamic && *rolls) {
        double q_end[MAX_STATE];
        dt = t_left / ceil(t_left / m->max_substep - 1e-9); /* equal substeps, exact end */
        memcpy(q_end, m->q, sizeof(q_end));
        model_rk4_step(m, q_end, dt);
        if (slip_wheels_roll(m, q_end)) {
            memcpy(m->q, q_end, sizeof(q_end));
            return dt; /* *rolls stays true: checked at the new state */
        }
        /* rolling needs more than friction before this substep ends: slide from its start */
    }
    if (!m->dynamic) {
        enter_dynamic(m);
    }
    dt = t_left / ceil(t_left / m->slip_substep - 1e-9);
    dynamic_step(m, dt);
    *rolls = !m->dynamic; /* back to rolling only after all_wheels_roll at the new state */
    return dt;
}
