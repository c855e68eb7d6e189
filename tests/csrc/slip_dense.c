/*
 * The dense friction solver of slip_mode 1, O(n^3) per substep: the reference the tests hold the
 * FMU's linear-time solver (fmu/src/slip_solver.c) equal to. It defines the same three functions
 * (slip_dynamic_step, slip_outputs, slip_onset_outputs) from the formulation in the note at the
 * top of fmu/src/slip.c: the LCP matrix A = J M^-1 J^T is formed and solved by projected
 * Gauss-Seidel, finished by an exact solve on the sticking set. tests/test_fmu_slip_reference.py
 * compiles it with the FMU's sources in place of slip_solver.c; it is never built into an FMU.
 */
#include <math.h>

#include "model.h"

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
   consistent at the end of the substep (see the note at the top of slip.c). */
void slip_dynamic_step(ModelData *m, double dt) {
    enum { nn = MAX_TRAILERS * MAX_TRAILERS };
    const int n = m->n;
    double mass[nn], g[MAX_TRAILERS], jac[nn], minv_jt[nn], a[nn], b[MAX_TRAILERS];
    double lim[MAX_TRAILERS], lam[MAX_TRAILERS], w_free[MAX_TRAILERS], w_new[MAX_TRAILERS];
    double vh[2], ah[2];
    /* zeroed because gcc cannot see that the loops fill the first n (ct, st: 1..n) */
    double th_end[MAX_TRAILERS] = {0.0}, ct[MAX_BODIES] = {0.0}, st[MAX_BODIES] = {0.0};
    double u_free[MAX_TRAILERS] = {0.0};
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

