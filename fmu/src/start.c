/*
 * Start values of TrailerTrain: every variable at its start (model_set_defaults, part of the
 * glue's model interface, fmu_model.h), the per-body arrays sized for n trailers and the state
 * from the start values. They come from start_values.h, which the builder renders from
 * fmu/variables.py (the modelDescription.xml states the same; a test checks them through the FMU).
 */
#include <string.h>

#include "model.h"
#include "start_values.h" /* START_<name>, generated from fmu/variables.py (Table 1 included) */

/* The per-body parameters and inputs at their start values for m->n trailers. */
static void set_array_defaults(ModelData *m) {
    const int n = m->n;
    int i;
    for (i = 0; i < MAX_BODIES; i++) {
        const bool trailer = i >= 1 && i <= n;
        m->front[i] = trailer ? START_front : 0.0;
        m->rear[i] = (i < n) ? START_rear : 0.0;
        m->mass[i] = trailer ? START_mass : 0.0;
        m->inertia[i] = trailer ? START_inertia : 0.0;
        m->payload[i] = trailer ? START_payload : 0.0;
        m->mu[i] = trailer ? START_mu : 0.0;
        m->theta_start[i] = (i <= n) ? START_theta_start : 0.0;
        m->slide[i] = trailer ? START_slide : 0.0;
    }
}

void model_set_defaults(ModelData *m) {
    memset(m, 0, sizeof(*m));
    m->n = DEFAULT_TRAILERS;
    set_array_defaults(m);
    m->g = START_g;
    m->robot_tau = START_robot_tau;
    m->robot_acc_max = START_robot_acc_max;
    m->robot_alpha_max = START_robot_alpha_max;
    m->slip_mode = START_slip_mode;
    m->phi_max = START_phi_max;
    m->x0_start = START_x0_start;
    m->y0_start = START_y0_start;
    m->v_start = START_v_start;
    m->w_start = START_w_start;
    m->max_substep = START_max_substep;
    m->slip_substep = START_slip_substep;
    m->v_cmd = START_v_cmd;
    m->w_cmd = START_w_cmd;
    m->push_x = START_push_x;
    m->push_y = START_push_y;
    m->time = 0.0;
    model_state_from_start(m);
}

void model_set_trailers(ModelData *m, int n) {
    m->n = n;
    set_array_defaults(m);
    model_state_from_start(m);
}

void model_state_from_start(ModelData *m) {
    int i;
    m->q[IX_X0] = m->x0_start;
    m->q[IX_Y0] = m->y0_start;
    for (i = 0; i <= m->n; i++) {
        m->q[IX_THETA + i] = m->theta_start[i];
    }
    m->q[IX_V0] = m->v_start;
    m->q[IX_W0] = m->w_start;
    m->dynamic = false;
    for (i = 0; i <= m->n; i++) {
        m->wt[i] = 0.0;
        m->alpha_dyn[i] = 0.0;
        m->f_dyn[i] = 0.0;
        m->F_lat_max[i] = (i >= 1) ? m->mu[i] * (m->mass[i] + m->payload[i]) * m->g : 0.0;
    }
    m->outputs_valid = false;
}

