/*
 * Lateral wheel forces by Newton-Euler, from trailer n down to trailer 1 (paper Sec. 3.2).
 *
 * Trailer i (mass centre at its axle midpoint, m_i = mass + payload, I_i about that point):
 *   m_i a_i   = f_i - f_{i+1} + F_d,i n_i (+ push on trailer n)
 *   I_i alpha_i = F_i n_i.f_i + R_i n_i.f_{i+1}
 * with f_i the force of body i-1 on trailer i at their hitch and f_{n+1} = 0. Wheels carry no
 * longitudinal force. Solving in the trailer's frame:
 *   n_i.f_i = (I_i alpha_i - R_i n_i.f_{i+1}) / F_i
 *   e_i.f_i = m_i a_i.e_i + e_i.f_{i+1} - e_i.push
 *   F_d,i  = m_i a_i.n_i - n_i.f_i + n_i.f_{i+1} - n_i.push
 * so F_d,i = m_i a_i.n_i - I_i alpha_i / F_i + (1 + R_i/F_i) n_i.f_{i+1}: the paper's Eq. (14)
 * (factor 2) for D = F = R. The axle acceleration with lateral sliding speed u_i (held constant
 * within a step) is a_i = (dv_i - u_i w_i) e_i + v_i w_i n_i.
 */
#include <math.h>

#include "model.h"

void lateral_forces(const ModelData *m, const double *q, const double *v, const double *w,
                    const double *dv, const double *dw, double *F_lat, double *hitch_fx,
                    double *hitch_fy) {
    const int n = m->n;
    double next_fx = 0.0, next_fy = 0.0; /* f_{i+1}, world frame */
    int i;
    for (i = n; i >= 1; i--) {
        const double theta = q[IX_THETA + i];
        const double ex = cos(theta), ey = sin(theta);
        const double nx = -ey, ny = ex;
        const double total_mass = m->mass[i] + m->payload[i];
        const double a_e = dv[i] - m->slide[i] * w[i];
        const double a_n = v[i] * w[i];
        const double push_x = (i == n) ? m->push_x : 0.0;
        const double push_y = (i == n) ? m->push_y : 0.0;
        const double next_e = ex * next_fx + ey * next_fy;
        const double next_n = nx * next_fx + ny * next_fy;
        const double push_e = ex * push_x + ey * push_y;
        const double push_n = nx * push_x + ny * push_y;
        const double rear_link = (i < n) ? m->rear[i] : 0.0;
        const double f_n = (m->inertia[i] * dw[i] - rear_link * next_n) / m->front[i];
        const double f_e = total_mass * a_e + next_e - push_e;
        F_lat[i] = total_mass * a_n - f_n + next_n - push_n;
        hitch_fx[i] = f_e * ex + f_n * nx;
        hitch_fy[i] = f_e * ey + f_n * ny;
        next_fx = hitch_fx[i];
        next_fy = hitch_fy[i];
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
