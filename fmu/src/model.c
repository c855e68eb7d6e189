/*
 * Combination checks, outputs and fixed-step integration of TrailerTrain, and its side of the
 * glue's model interface (fmu_model.h): initialization, outputs, the step. The start values are
 * start.c's, the physics chain.c's, forces.c's, slip.c's and slip_solver.c's.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "model.h"

#define PT_PI 3.14159265358979323846

bool model_check_combinations(const ModelData *m, char *msg, size_t len) {
    int i;
    for (i = 1; i <= m->n; i++) {
        if (m->slip_mode == 1 && m->slide[i] != 0.0) {
            snprintf(msg, len, "slip_mode = 1 with slide[%d] = %g: an imposed slide is the "
                     "kinematic disturbance of slip_mode 0; with slip_mode = 1 push the trailer "
                     "with push_x, push_y instead (or set slide[%d] = 0)", i, m->slide[i], i);
            return false;
        }
    }
    return true;
}

static double wrap_angle(double angle) {
    double wrapped = fmod(angle + PT_PI, 2.0 * PT_PI);
    if (wrapped < 0.0) {
        wrapped += 2.0 * PT_PI;
    }
    wrapped -= PT_PI;
    return (wrapped <= -PT_PI) ? PT_PI : wrapped;
}

/* Rolling outputs at the state: velocities, and the wheel and hitch forces rolling needs. */
static void rolling_outputs(ModelData *m, double *F_lat, double *hitch_fx, double *hitch_fy) {
    double c[MAX_BODIES], s[MAX_BODIES], dv[MAX_BODIES], dw[MAX_BODIES];
    double dv0, dw0;
    chain_velocities(m, m->q, c, s, m->v, m->w);
    robot_accelerations(m, m->q, &dv0, &dw0);
    chain_accelerations(m, c, s, m->v, m->w, dv0, dw0, dv, dw);
    lateral_forces(m, m->q, m->v, m->w, dv, dw, F_lat, hitch_fx, hitch_fy);
}

void model_compute_outputs(ModelData *m) {
    bool sliding = m->dynamic; /* the wheel forces follow Coulomb's law, not rolling */
    int i;
    if (m->dynamic) {
        slip_outputs(m); /* some wheel slides: velocities and forces from the dynamics */
    } else {
        rolling_outputs(m, m->F_lat, m->hitch_fx, m->hitch_fy);
        for (i = 1; i <= m->n; i++) {
            m->slide_speed[i] = m->slide[i];
            if (m->slip_mode == 1 && fabs(m->F_lat[i]) > m->F_lat_max[i]) {
                sliding = true; /* rolling would need more than friction with these inputs */
            }
        }
        if (sliding) {
            slip_onset_outputs(m);
        }
    }

    m->x[0] = m->q[IX_X0];
    m->y[0] = m->q[IX_Y0];
    m->phi[0] = 0.0;
    m->jackknifed = false;
    for (i = 1; i <= m->n; i++) {
        const double th_prev = m->q[IX_THETA + i - 1], th = m->q[IX_THETA + i];
        const double r = m->rear[i - 1], f = m->front[i];
        m->x[i] = m->x[i - 1] - r * cos(th_prev) - f * cos(th);
        m->y[i] = m->y[i - 1] - r * sin(th_prev) - f * sin(th);
        m->phi[i] = wrap_angle(th_prev - th);
        m->F_lat_max[i] = m->mu[i] * (m->mass[i] + m->payload[i]) * m->g;
        if (sliding) {
            m->slipping[i] = fabs(m->slide_speed[i]) > 1e-6
                             || fabs(m->F_lat[i]) >= m->F_lat_max[i] * (1.0 - 1e-9);
        } else {
            m->slipping[i] = fabs(m->F_lat[i]) > m->F_lat_max[i];
        }
        if (fabs(m->phi[i]) > m->phi_max) {
            m->jackknifed = true;
        }
    }
    m->outputs_valid = true;
}

bool model_state_is_finite(const ModelData *m) {
    int k;
    for (k = 0; k < N_STATE(m); k++) {
        if (!isfinite(m->q[k])) {
            return false;
        }
    }
    return true;
}

bool model_outputs_are_finite(const ModelData *m) {
    int i;
    for (i = 0; i <= m->n; i++) {
        if (!isfinite(m->x[i]) || !isfinite(m->y[i]) || !isfinite(m->v[i]) || !isfinite(m->w[i])
            || !isfinite(m->slide_speed[i]) || !isfinite(m->wt[i])
            || !isfinite(m->F_lat[i]) || !isfinite(m->hitch_fx[i]) || !isfinite(m->hitch_fy[i])) {
            return false;
        }
    }
    return true;
}


void model_integrate(ModelData *m, double h, double t_end) {
    if (m->slip_mode == 1) {
        double t_left = h;
        /* the inputs may have changed since the last step: check the start again */
        bool rolls = !m->dynamic && slip_wheels_roll(m, m->q);
        while (t_left > 0.0) {
            t_left -= slip_advance(m, t_left, &rolls);
        }
    } else {
        /* Equal substeps no longer than max_substep; the guard keeps h = max_substep one step. */
        int substeps = (int)ceil(h / m->max_substep - 1e-9);
        double dt;
        int k;
        if (substeps < 1) {
            substeps = 1;
        }
        dt = h / substeps;
        for (k = 0; k < substeps; k++) {
            model_rk4_step(m, m->q, dt);
        }
    }
    m->time = t_end;
    m->outputs_valid = false;
}

/* ---------------------------------------------------------------- the glue's model interface */

bool model_instantiate(ModelData *m, const char *resource_location, char *msg, size_t len) {
    (void)m; /* model_set_defaults follows */
    (void)resource_location; /* no resources are needed; any file: spelling is accepted */
    (void)msg;
    (void)len;
    return true;
}

void model_free(ModelData *m) {
    (void)m; /* plain data: nothing to release */
}

void model_set_start_time(ModelData *m, double start_time) {
    m->time = start_time;
}

double model_time(const ModelData *m) {
    return m->time;
}

/* The outputs are a cache: computed after each step, after the end of initialization and at the
   first read after a set, and kept while outputs_valid, which every set clears (setting an input
   changes F_lat; before initialization ends, setting a parameter or a start value changes every
   output). outputs_valid implies a finite state and finite outputs, so a read of current outputs
   costs O(1) here; a read after a set costs O(n) once. Before initialization ends the outputs
   follow the (possibly changed) start parameters, which must then be valid; after an error with
   a non-finite state there are none. */
bool model_update_outputs(ModelData *m, ModelPhase phase, char *msg, size_t len) {
    char why[512];
    if (m->outputs_valid) {
        return true;
    }
    if (phase <= phase_initialization) {
        if (!model_check_parameters(m, why, sizeof(why))) {
            snprintf(msg, len, "outputs cannot be computed: %s", why);
            return false;
        }
        model_state_from_start(m);
    }
    if (!model_state_is_finite(m)) {
        snprintf(msg, len, "the state is non-finite after an error: no outputs");
        return false;
    }
    model_compute_outputs(m);
    if (!model_outputs_are_finite(m)) {
        m->outputs_valid = false;
        snprintf(msg, len, "outputs became non-finite at t = %.9g (overflow of the forces: "
                 "velocities %g m/s, %g rad/s of the robot)", m->time, m->q[IX_V0], m->q[IX_W0]);
        return false;
    }
    return true;
}

bool model_exit_initialization(ModelData *m, char *msg, size_t len) {
    if (!model_check_parameters(m, msg, len) || !model_check_combinations(m, msg, len)) {
        return false;
    }
    model_state_from_start(m);
    model_compute_outputs(m);
    if (!model_outputs_are_finite(m)) {
        m->outputs_valid = false;
        snprintf(msg, len, "the start values give non-finite outputs (v_start = %g, w_start = %g, "
                 "v_cmd = %g, w_cmd = %g)", m->v_start, m->w_start, m->v_cmd, m->w_cmd);
        return false;
    }
    return true;
}

bool model_do_step(ModelData *m, double t, double h, double tolerance, char *msg, size_t len) {
    (void)tolerance; /* fixed substeps to exactly t + h */
    if (h / m->max_substep > 1e9) {
        snprintf(msg, len, "communicationStepSize = %g s needs more than 1e9 substeps of "
                 "max_substep = %g s", h, m->max_substep);
        return false;
    }
    m->time = t;
    model_integrate(m, h, t + h);
    if (model_state_is_finite(m)) {
        model_compute_outputs(m); /* outputs of the new point, checked once here */
    }
    if (!model_state_is_finite(m) || !model_outputs_are_finite(m)) {
        m->outputs_valid = false; /* a later read fails instead of returning them */
        snprintf(msg, len, "the state or outputs became non-finite in the step from t = %.9g to "
                 "%.9g (inputs v_cmd = %g, w_cmd = %g)", t, t + h, m->v_cmd, m->w_cmd);
        return false;
    }
    return true;
}
