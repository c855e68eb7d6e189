/*
 * Chain kinematics of the off-hooked trailer train and its time derivatives.
 *
 * Body i-1's rear hitch P_{i-1} - R_{i-1} e_{i-1} coincides with trailer i's front hitch
 * P_i + F_i e_i. Body i moves with longitudinal speed v_i along e_i and lateral speed u_i along
 * n_i (u_0 = 0: the robot's velocity loop holds it; u_i = slide[i] for trailers, 0 when
 * rolling). Projecting the hitch velocity onto e_i and n_i, with c = cos phi_i, s = sin phi_i:
 *
 *   v_i = c v_{i-1} + s (R_{i-1} w_{i-1} - u_{i-1})
 *   w_i = (s v_{i-1} + c (u_{i-1} - R_{i-1} w_{i-1}) - u_i) / F_i
 *
 * which for u = 0 is the no-slip map (the inverse of the paper's Eq. 5).
 */
#include <math.h>
#include <string.h>

#include "model.h"

void chain_velocities(const ModelData *m, const double *q, double *c, double *s, double *v,
                      double *w) {
    int i;
    v[0] = q[IX_V0];
    w[0] = q[IX_W0];
    c[0] = 1.0;
    s[0] = 0.0;
    for (i = 1; i <= m->n; i++) {
        const double phi = q[IX_THETA + i - 1] - q[IX_THETA + i];
        const double u_prev = (i == 1) ? 0.0 : m->slide[i - 1];
        const double r = m->rear[i - 1];
        c[i] = cos(phi);
        s[i] = sin(phi);
        v[i] = c[i] * v[i - 1] + s[i] * (r * w[i - 1] - u_prev);
        w[i] = (s[i] * v[i - 1] + c[i] * (u_prev - r * w[i - 1]) - m->slide[i]) / m->front[i];
    }
}

void robot_accelerations(const ModelData *m, const double *q, double *dv0, double *dw0) {
    *dv0 = pt_clamp((m->v_cmd - q[IX_V0]) / m->robot_tau, -m->robot_acc_max, m->robot_acc_max);
    *dw0 = pt_clamp((m->w_cmd - q[IX_W0]) / m->robot_tau, -m->robot_alpha_max, m->robot_alpha_max);
}

void chain_derivatives(const ModelData *m, const double *q, double *dq) {
    double c[MAX_BODIES], s[MAX_BODIES], v[MAX_BODIES], w[MAX_BODIES];
    int i;
    chain_velocities(m, q, c, s, v, w);
    dq[IX_X0] = v[0] * cos(q[IX_THETA]);  /* robot moves along its heading */
    dq[IX_Y0] = v[0] * sin(q[IX_THETA]);
    for (i = 0; i <= m->n; i++) {
        dq[IX_THETA + i] = w[i];
    }
    robot_accelerations(m, q, &dq[IX_V0], &dq[IX_W0]);
}

/*
 * Differentiating the velocity map (u_i held constant within a step), with phidot = w_{i-1} - w_i:
 *   dv_i = -s phidot v_{i-1} + c dv_{i-1} + c phidot (R w_{i-1} - u_{i-1}) + s R dw_{i-1}
 *   dw_i = (c phidot v_{i-1} + s dv_{i-1} - s phidot (u_{i-1} - R w_{i-1}) - c R dw_{i-1}) / F_i
 */
void chain_accelerations(const ModelData *m, const double *c, const double *s, const double *v,
                         const double *w, double dv0, double dw0, double *dv, double *dw) {
    int i;
    dv[0] = dv0;
    dw[0] = dw0;
    for (i = 1; i <= m->n; i++) {
        const double u_prev = (i == 1) ? 0.0 : m->slide[i - 1];
        const double r = m->rear[i - 1];
        const double phidot = w[i - 1] - w[i];
        const double lateral_prev = r * w[i - 1] - u_prev; /* -(hitch velocity . n_{i-1}) */
        dv[i] = -s[i] * phidot * v[i - 1] + c[i] * dv[i - 1] + c[i] * phidot * lateral_prev
                + s[i] * r * dw[i - 1];
        dw[i] = (c[i] * phidot * v[i - 1] + s[i] * dv[i - 1] + s[i] * phidot * lateral_prev
                 - c[i] * r * dw[i - 1]) / m->front[i];
    }
}

/* One classical RK4 step of the rolling (kinematic) model. */
void model_rk4_step(const ModelData *m, double *q, double dt) {
    double k1[MAX_STATE], k2[MAX_STATE], k3[MAX_STATE], k4[MAX_STATE];
    double tmp[MAX_STATE] = {0.0}; /* beyond n_state never read (gcc cannot see it inlined) */
    const int n_state = N_STATE(m);
    int k;
    chain_derivatives(m, q, k1);
    for (k = 0; k < n_state; k++) tmp[k] = q[k] + 0.5 * dt * k1[k];
    chain_derivatives(m, tmp, k2);
    for (k = 0; k < n_state; k++) tmp[k] = q[k] + 0.5 * dt * k2[k];
    chain_derivatives(m, tmp, k3);
    for (k = 0; k < n_state; k++) tmp[k] = q[k] + dt * k3[k];
    chain_derivatives(m, tmp, k4);
    for (k = 0; k < n_state; k++) {
        q[k] += dt / 6.0 * (k1[k] + 2.0 * k2[k] + 2.0 * k3[k] + k4[k]);
    }
}

void robot_hitch(const ModelData *m, const double *q, double *vh, double *ah) {
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

void robot_rk4(const ModelData *m, double *q, double dt) {
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
