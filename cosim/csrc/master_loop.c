/*
 * The co-simulation master's step loop (master_loop.h). Every formula is the Python loop's
 * (cosim/master.py, cosim/events.py; the sensors are core/csrc/sensors.c, the Python loop's
 * too) in the same order, compiled with -ffp-contract=off, so a run gives the Python loop's
 * numbers bit for bit (tests/test_master_loop.py).
 */
#include "master_loop.h"

#include <math.h>
#include <string.h>

#define PT_EPS_T 1e-12 /* [s] event times against communication points (events.py) */

size_t pt_master_loop_sizeof(void) { return sizeof(PtMasterLoop); }

static int valid(const PtMasterLoop *m) {
    return m->component != NULL && m->get_real != NULL && m->set_real != NULL &&
           m->get_boolean != NULL && m->do_step != NULL && m->state_vr != NULL &&
           m->input_vr != NULL && m->output_vr != NULL && m->flag_vr != NULL && m->n >= 1 &&
           m->n_outputs >= 1 && m->n_output_runs >= 1 && m->output_runs != NULL &&
           m->flag_at != NULL && m->scalar_at != NULL && m->outputs != NULL &&
           m->instant != NULL && m->instant->track != NULL && m->instant->sensors != NULL &&
           m->instant->sensors->n == m->n && m->instant->sensors->bias != NULL &&
           (m->instant->sensors->half_backlash == 0.0 || m->instant->sensors->play != NULL) &&
           (m->instant->sensors->noise == 0 ||
            (m->noise_values != NULL &&
             m->noise_per_step == pt_sensors_noise_count(m->instant->sensors))) &&
           m->rows != NULL && m->f_lat_max != NULL && m->state != NULL && m->flags != NULL &&
           (m->instant->n_pushes == 0 || m->instant->pushes != NULL) &&
           (m->n_slide_writes == 0 || (m->slide_vr != NULL && m->slide_values != NULL));
}

int pt_master_run(PtMasterLoop *m, long k_first, long k_stop) {
    const PtTrack *track;
    int reason = PT_LOOP_PAUSE;
    long k;
    if (m == NULL || !valid(m)) {
        return PT_LOOP_ARGUMENT;
    }
    if (k_first < 0 || k_first > m->n_steps || k_stop <= k_first) {
        m->k = k_first;
        return PT_LOOP_ARGUMENT;
    }
    track = m->instant->track;
    for (k = k_first; k < k_stop; k++) {
        const long j = k - k_first;
        const double t = m->t0 + (double)k * m->step;
        double *row = m->rows + (size_t)j * (size_t)m->row_width;
        double *phi_meas = row + m->at_phi_meas;
        const int *at = m->scalar_at;
        const double *noise = m->instant->sensors->noise
                                  ? m->noise_values + (size_t)j * m->noise_per_step : NULL;
        int status, i;
        m->k = k;
        if (j > 0 && (t >= m->pause_at || m->next_bias <= t + PT_EPS_T)) {
            reason = PT_LOOP_PAUSE;
            break;
        }
        /* apply inputs: states -> the engine's step (sensors, law, push) -> FMU inputs */
        status = m->get_real(m->component, m->state_vr, (size_t)(m->n + 6), m->state);
        if (status > 1) {
            m->failed_call = PT_CALL_GET_STATE;
            m->fmi_status = status;
            reason = PT_LOOP_FMI_ERROR;
            break;
        }
        status = pt_step(m->instant, t, m->state, noise, phi_meas);
        if (status != PT_OK) {
            m->control_status = status;
            reason = PT_LOOP_CONTROL_ERROR;
            break;
        }
        m->inputs[0] = track->cmd[0], m->inputs[1] = track->cmd[1];
        m->inputs[2] = m->instant->push[0], m->inputs[3] = m->instant->push[1];
        status = m->set_real(m->component, m->input_vr, 4, m->inputs);
        if (status > 1) {
            m->failed_call = PT_CALL_SET_INPUTS;
            m->fmi_status = status;
            reason = PT_LOOP_FMI_ERROR;
            break;
        }
        if (j == 0) {
            for (i = 0; i < m->n_slide_writes; i++) { /* one call per trailer, as PythonLoop */
                status = m->set_real(m->component, m->slide_vr + i, 1, m->slide_values + i);
                if (status > 1) {
                    m->failed_call = PT_CALL_SET_SLIDE;
                    m->fmi_status = status;
                    break;
                }
            }
            if (status > 1) {
                m->failed_slide = i;
                reason = PT_LOOP_FMI_ERROR;
                break;
            }
        }
        /* record: the outputs and flags, then the scalars */
        status = m->get_real(m->component, m->output_vr, (size_t)m->n_outputs, m->outputs);
        if (status > 1) {
            m->failed_call = PT_CALL_GET_OUTPUTS;
            m->fmi_status = status;
            reason = PT_LOOP_FMI_ERROR;
            break;
        }
        status = m->get_boolean(m->component, m->flag_vr, (size_t)(m->n + 1), m->flags);
        if (status > 1) {
            m->failed_call = PT_CALL_GET_FLAGS;
            m->fmi_status = status;
            reason = PT_LOOP_FMI_ERROR;
            break;
        }
        for (i = 0; i < m->n_output_runs; i++) {
            const int *run = m->output_runs + 3 * i;
            memcpy(row + run[1], m->outputs + run[0], (size_t)run[2] * sizeof(double));
        }
        for (i = 0; i <= m->n; i++) {
            row[m->flag_at[i]] = (double)m->flags[i];
        }
        memcpy(row + m->at_f_lat_max, m->f_lat_max, (size_t)m->n * sizeof(double));
        row[at[0]] = t;
        row[at[1]] = m->inputs[0];
        row[at[2]] = m->inputs[1];
        row[at[3]] = m->inputs[2];
        row[at[4]] = m->inputs[3];
        row[at[5]] = m->slide;
        row[at[6]] = track->sample.x;
        row[at[7]] = track->sample.y;
        row[at[8]] = track->sample.theta;
        row[at[9]] = track->sample.v;
        row[at[10]] = track->sample.w;
        row[at[11]] = (double)track->sample.direction;
        row[at[12]] = m->instant->errors[0];
        row[at[13]] = m->instant->errors[1];
        row[at[14]] = m->instant->errors[2];
        if (m->flags[m->n] != 0) {
            reason = PT_LOOP_JACKKNIFE;
            break;
        }
        if (m->check_goal && t >= m->goal_from) {
            const double *last = m->state + 3; /* the last trailer's true pose */
            const double dist = hypot(last[0] - m->goal_x, last[1] - m->goal_y);
            if (dist <= m->goal_position * (1.0 + m->goal_slack) &&
                fabs(pt_wrap(last[2] - m->goal_theta)) <= m->goal_heading * (1.0 + m->goal_slack)) {
                reason = PT_LOOP_GOAL_CANDIDATE;
                break;
            }
        }
        if (k == m->n_steps) {
            reason = PT_LOOP_HORIZON;
            break;
        }
        /* do step */
        status = m->do_step(m->component, t, m->step, 1);
        if (status > 1) {
            m->failed_call = PT_CALL_DO_STEP;
            m->fmi_status = status;
            reason = PT_LOOP_FMI_ERROR;
            break;
        }
        m->time = t + m->step;
        m->k = k + 1;
    }
    return reason;
}
