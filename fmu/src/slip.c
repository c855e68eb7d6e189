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
 * exactly (u_S = 0 with the sliding impulses lambda_L at their bounds), see "Linear time"
 * in slip_solver.c.
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
 * The friction solver that takes a substep of the dynamic regime and computes its outputs
 * (slip_dynamic_step, slip_outputs, slip_onset_outputs) is slip_solver.c, in linear time; the
 * dense O(n^3) solver it replaced is the independent reference of the tests
 * (tests/csrc/slip_dense.c, built and compared by tests/test_fmu_slip_reference.py).
 */
#include <math.h>
#include <string.h>

#include "model.h"

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
    slip_dynamic_step(m, dt);
    *rolls = !m->dynamic; /* back to rolling only after all_wheels_roll at the new state */
    return dt;
}
