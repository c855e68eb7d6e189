/*
 * The co-simulation master's step loop (master_loop.h), compiled with -ffp-contract=off like the
 * engine. tests/reference/master_loop.py is the same loop written step by step in Python; the
 * tests hold the two equal bit for bit (tests/test_master_loop.py).
 */
#include "master_loop.h"

#include <math.h>
#include <stdbool.h>
#include <string.h>

#define PT_EPS_T 1e-12 /* [s] event times against communication points (events.py) */

/* FMI 2.0 (fmi2Functions.h: fmi2Component = void *, fmi2ValueReference = unsigned int,
 * fmi2Boolean = int, fmi2Status = int) */
typedef int (*Fmi2GetReal)(void *, const unsigned int *, size_t, double *);
typedef int (*Fmi2SetReal)(void *, const unsigned int *, size_t, const double *);
typedef int (*Fmi2GetBoolean)(void *, const unsigned int *, size_t, int *);
typedef int (*Fmi2DoStep)(void *, double, double, int);
/* FMI 3.0 (fmi3Functions.h: fmi3Instance = void *, fmi3ValueReference = uint32, fmi3Boolean =
 * bool, fmi3Status = int) */
typedef int (*Fmi3GetFloat64)(void *, const unsigned int *, size_t, double *, size_t);
typedef int (*Fmi3SetFloat64)(void *, const unsigned int *, size_t, const double *, size_t);
typedef int (*Fmi3GetBoolean)(void *, const unsigned int *, size_t, bool *, size_t);
typedef int (*Fmi3DoStep)(void *, double, double, bool, bool *, bool *, bool *, double *);

size_t pt_master_loop_sizeof(void) { return sizeof(PtMasterLoop); }

static int read_valid(const PtFmuRead *r) {
    return r->vr != NULL && r->nvr >= 1 && r->count >= r->nvr && r->n_named >= 1 &&
           r->values != NULL && (r->index != NULL || r->n_named <= r->count);
}

static int valid(const PtMasterLoop *m) {
    const PtSensors *s;
    if (m->component == NULL || m->get_real == NULL || m->set_real == NULL ||
        m->get_boolean == NULL || m->do_step == NULL || m->input_vr == NULL || m->n < 1 ||
        (m->fmi_version != 2 && m->fmi_version != 3) || !read_valid(&m->state) ||
        !read_valid(&m->outputs) || !read_valid(&m->flags) || m->state.n_named != m->n + 6 ||
        m->flags.n_named != m->n + 1 || m->output_at == NULL || m->flag_at == NULL ||
        m->scalar_at == NULL || m->rows == NULL || m->f_lat_max == NULL || m->truth == NULL) {
        return 0;
    }
    if (m->engine == NULL) {
        return m->hook != NULL && m->hook_out != NULL && m->hook_phi != NULL;
    }
    s = m->engine->sensors;
    return (m->engine->track != NULL) != (m->engine->profile != NULL) && s != NULL &&
           s->n == m->n && s->bias != NULL &&
           (s->half_backlash == 0.0 || s->play != NULL) &&
           (s->noise == 0 ||
            (m->noise_values != NULL && m->noise_per_step == pt_sensors_noise_count(s))) &&
           (m->engine->n_pushes == 0 || m->engine->pushes != NULL);
}

static int get_reals(const PtMasterLoop *m, const PtFmuRead *r) {
    if (m->fmi_version == 2) {
        return ((Fmi2GetReal)m->get_real)(m->component, r->vr, (size_t)r->nvr,
                                          (double *)r->values);
    }
    return ((Fmi3GetFloat64)m->get_real)(m->component, r->vr, (size_t)r->nvr,
                                         (double *)r->values, (size_t)r->count);
}

/* The j-th named value of read r. */
static double real_at(const PtFmuRead *r, int j) {
    return ((const double *)r->values)[r->index != NULL ? r->index[j] : j];
}

static double flag_at(const PtMasterLoop *m, int j) {
    const PtFmuRead *r = &m->flags;
    const int i = r->index != NULL ? r->index[j] : j;
    if (m->fmi_version == 2) {
        return (double)((const int *)r->values)[i];
    }
    return (double)((const bool *)r->values)[i];
}

static int set_inputs(const PtMasterLoop *m) {
    if (m->fmi_version == 2) {
        return ((Fmi2SetReal)m->set_real)(m->component, m->input_vr, 4, m->inputs);
    }
    return ((Fmi3SetFloat64)m->set_real)(m->component, m->input_vr, 4, m->inputs, 4);
}

static int get_flags(const PtMasterLoop *m) {
    const PtFmuRead *r = &m->flags;
    if (m->fmi_version == 2) {
        return ((Fmi2GetBoolean)m->get_boolean)(m->component, r->vr, (size_t)r->nvr,
                                                (int *)r->values);
    }
    return ((Fmi3GetBoolean)m->get_boolean)(m->component, r->vr, (size_t)r->nvr,
                                            (bool *)r->values, (size_t)r->count);
}

static int do_step(const PtMasterLoop *m, double t) {
    if (m->fmi_version == 2) {
        return ((Fmi2DoStep)m->do_step)(m->component, t, m->step, 1);
    }
    {
        bool event = false, terminate = false, early = false;
        double last = 0.0;
        return ((Fmi3DoStep)m->do_step)(m->component, t, m->step, true, &event, &terminate,
                                        &early, &last);
    }
}

/* The step's closed-loop work into out (PT_OUT_*) and phi_meas; PT_OK or the refusal. */
static int closed_loop(PtMasterLoop *m, double t, long j, double *phi_meas, double *out) {
    const PtStep *step;
    int status;
    if (m->engine == NULL) {
        status = m->hook(m->hook_user, t);
        if (status != 0) {
            return status;
        }
        memcpy(out, m->hook_out, PT_OUT_COUNT * sizeof(double));
        memcpy(phi_meas, m->hook_phi, (size_t)m->n * sizeof(double));
        return PT_OK;
    }
    status = pt_step(m->engine, t, m->truth,
                     m->engine->sensors->noise ? m->noise_values + (size_t)j * m->noise_per_step
                                               : NULL,
                     phi_meas);
    if (status != PT_OK) {
        return status;
    }
    step = m->engine;
    out[PT_OUT_V_CMD] = step->cmd[0];
    out[PT_OUT_W_CMD] = step->cmd[1];
    out[PT_OUT_PUSH_X] = step->push[0];
    out[PT_OUT_PUSH_Y] = step->push[1];
    out[PT_OUT_X_D] = step->sample.x;
    out[PT_OUT_Y_D] = step->sample.y;
    out[PT_OUT_THETA_D] = step->sample.theta;
    out[PT_OUT_V_D] = step->sample.v;
    out[PT_OUT_W_D] = step->sample.w;
    out[PT_OUT_DIRECTION] = (double)step->sample.direction;
    out[PT_OUT_E_LON] = step->errors[0];
    out[PT_OUT_E_LAT] = step->errors[1];
    out[PT_OUT_E_THETA] = step->errors[2];
    return PT_OK;
}

#define FAIL(call, st)                    \
    do {                                  \
        m->failed_call = (call);          \
        m->fmi_status = (st);             \
        reason = PT_LOOP_FMI_ERROR;       \
        goto done;                        \
    } while (0)

int pt_master_run(PtMasterLoop *m, long k_first, long k_stop) {
    int reason = PT_LOOP_PAUSE;
    long k;
    if (m == NULL || !valid(m)) {
        return PT_LOOP_ARGUMENT;
    }
    if (k_first < 0 || k_first > m->n_steps || k_stop <= k_first) {
        m->k = k_first;
        return PT_LOOP_ARGUMENT;
    }
    for (k = k_first; k < k_stop; k++) {
        const long j = k - k_first;
        const double t = m->t0 + (double)k * m->step;
        double *row = m->rows + (size_t)j * (size_t)m->row_width;
        const int *at = m->scalar_at;
        double out[PT_OUT_COUNT];
        int status, i;
        m->k = k;
        if (j > 0 && (t >= m->pause_at || m->next_bias <= t + PT_EPS_T)) {
            reason = PT_LOOP_PAUSE;
            break;
        }
        /* apply inputs: states -> the closed-loop work (sensors, law, push) -> FMU inputs */
        status = get_reals(m, &m->state);
        if (status > 1) {
            FAIL(PT_CALL_GET_STATE, status);
        }
        for (i = 0; i < m->n + 6; i++) {
            m->truth[i] = real_at(&m->state, i);
        }
        status = closed_loop(m, t, j, row + m->at_phi_meas, out);
        if (status != PT_OK) {
            m->control_status = status;
            reason = PT_LOOP_CONTROL_ERROR;
            break;
        }
        memcpy(m->inputs, out, 4 * sizeof(double)); /* v_cmd, w_cmd, push_x, push_y */
        status = set_inputs(m);
        if (status > 1) {
            FAIL(PT_CALL_SET_INPUTS, status);
        }
        /* record: the outputs and flags, then the scalars */
        status = get_reals(m, &m->outputs);
        if (status > 1) {
            FAIL(PT_CALL_GET_OUTPUTS, status);
        }
        status = get_flags(m);
        if (status > 1) {
            FAIL(PT_CALL_GET_FLAGS, status);
        }
        for (i = 0; i < m->outputs.n_named; i++) {
            row[m->output_at[i]] = real_at(&m->outputs, i);
        }
        for (i = 0; i <= m->n; i++) {
            row[m->flag_at[i]] = flag_at(m, i);
        }
        memcpy(row + m->at_f_lat_max, m->f_lat_max, (size_t)m->n * sizeof(double));
        row[at[0]] = t;
        for (i = 0; i < 4; i++) {
            row[at[1 + i]] = out[i];
        }
        row[at[5]] = m->slide;
        for (i = PT_OUT_X_D; i < PT_OUT_COUNT; i++) {
            row[at[2 + i]] = out[i];
        }
        if (row[m->flag_at[m->n]] != 0.0) {
            reason = PT_LOOP_JACKKNIFE;
            break;
        }
        if (m->check_goal && t >= m->goal_from) {
            const double *last = m->truth + 3; /* the last trailer's true pose */
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
        status = do_step(m, t);
        if (status > 1) {
            FAIL(PT_CALL_DO_STEP, status);
        }
        m->time = t + m->step;
        m->k = k + 1;
    }
done:
    return reason;
}
