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
