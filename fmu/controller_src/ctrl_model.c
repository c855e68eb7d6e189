/*
 * The BackwardController model (see ctrl_model.h): the law itself is control.c, pushtrain's one
 * control law in C; this file feeds it the FMU's variables and the mission table.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ctrl_model.h"
#include "step.h"

static const char *law_error(int status) {
    switch (status) {
    case PT_ERR_NONFINITE_MEASUREMENT: return "a measured pose or joint angle is not finite";
    case PT_ERR_NONFINITE_COMMAND: return "the law gave a non-finite command";
    case PT_ERR_NO_LEADER: return "pulling without the robot's reference";
    case PT_ERR_DIRECTION: return "a reference direction that is not +1, -1 or 0";
    case PT_ERR_ARGUMENT: return "a bad argument (chain, table)";
    case PT_ERR_CAPACITY: return "the reference table is too long";
    case PT_ERR_SEGMENT: return "a segment the reference refuses";
    case PT_ERR_NOT_IN_PULL: return "the table's leader runs do not cover this pulling time";
    case PT_ERR_EMPTY_REFERENCE: return "a reference without segments";
    default: break;
    }
    return "unknown error";
}

int ctrl_model_init(CtrlModel *m, const CtrlTable *table, char *msg, size_t len) {
    const int capacity = 2 * table->n_segments + 1;
    PtSample end;
    int k, status;
    memset(m, 0, sizeof(*m));
    m->table = table;
    m->phases = (PtPhase *)calloc((size_t)capacity, sizeof(PtPhase));
    if (m->phases == NULL) {
        snprintf(msg, len, "out of memory for %d reference phases", capacity);
        return 0;
    }
    status = pt_reference_init(&m->reference, m->phases, capacity, table->start, table->speed,
                               table->cusp_dwell, table->t0, 0);
    for (k = 0; status == PT_OK && k < table->n_segments; k++) {
        status = pt_reference_append(&m->reference, &table->segments[k]);
    }
    if (status == PT_OK) {
        status = pt_reference_sample(&m->reference, m->reference.t_end, &end);
    }
    if (status != PT_OK) {
        snprintf(msg, len, "the mission table's reference is refused at segment %d: %s",
                 k, law_error(status));
        ctrl_model_free(m);
        return 0;
    }
    m->goal[0] = end.x;
    m->goal[1] = end.y;
    m->goal[2] = pt_wrap(end.theta);
    m->leader.n_runs = table->n_runs;
    m->leader.offset = table->offset;
    m->leader.t = table->t;
    m->leader.x = table->x;
    m->leader.y = table->y;
    m->leader.theta = table->theta;
    m->leader.v = table->v;
    m->leader.w = table->w;
    ctrl_model_set_defaults(m);
    return 1;
}

void ctrl_model_free(CtrlModel *m) {
    free(m->phases);
    m->phases = NULL;
}

void ctrl_model_set_defaults(CtrlModel *m) {
    memcpy(m->r, ctrl_real_start, sizeof(m->r));
    memcpy(m->i, ctrl_integer_start, sizeof(m->i));
    memcpy(m->b, ctrl_boolean_start, sizeof(m->b));
    m->r[R_t_end] = m->reference.t_end;
    m->time = 0.0;
    ctrl_model_start(m);
}

int ctrl_model_check_parameters(const CtrlModel *m, char *msg, size_t len) {
    int vr;
    for (vr = 1; vr < CTRL_VR_END; vr++) {
        const CtrlVarInfo *v = &ctrl_vars[vr];
        double value;
        if (v->name == NULL || v->causality != ctrl_parameter || v->type != ctrl_real) {
            continue;
        }
        value = m->r[v->offset];
        if (v->bounded && !(value >= v->min && value <= v->max)) {
            if (v->max == HUGE_VAL) {
                snprintf(msg, len, "%s = %g: allowed >= %g %s (%s)", v->name, value, v->min,
                         v->unit, v->reason);
            } else {
                snprintf(msg, len, "%s = %g: allowed %g to %g %s (%s)", v->name, value, v->min,
                         v->max, v->unit, v->reason);
            }
            return 0;
        }
        if (!isfinite(value)) {
            snprintf(msg, len, "%s = %g: must be finite", v->name, value);
            return 0;
        }
    }
    return 1;
}

void ctrl_model_start(CtrlModel *m) {
    const double dt = m->r[R_dt_start];
    memset(&m->memory, 0, sizeof(m->memory));
    /* BackwardController.reset(v_start, w_start, t0 - step) as pushtrain's master does */
    pt_control_reset(&m->memory.state, m->r[R_v_start], m->r[R_w_start], m->time - dt,
                     dt > 0.0);
    m->next = m->memory;
    m->evaluated = false;
    m->have_next = false;
}

/* The joint readings of the inputs phi (core/csrc/sensors.c, noise aside): the play advances
 * in next, the memory committed at the step. */
static void measure_joints(const CtrlModel *m, CtrlMemory *next, double *phi_meas) {
    PtSensors sensors;
    sensors.n = CTRL_N;
    sensors.bias = &m->r[R_joint_bias];
    sensors.half_backlash = 0.5 * m->r[R_joint_backlash];
    sensors.quantization = m->r[R_joint_quantization];
    sensors.noise = 0;
    sensors.measure_last_pose = 0;
    sensors.play = next->play;
    sensors.has_play = next->play_valid;
    pt_measure_joints(&sensors, &m->r[R_phi], NULL, phi_meas);
    next->play_valid = sensors.has_play;
}

static void set_outputs(CtrlModel *m, const PtSample *ref, const PtControlInfo *info,
                        const double cmd[2], const double *phi_meas, int done) {
    double errors[3];
    int k;
    m->r[R_v_cmd] = cmd[0];
    m->r[R_w_cmd] = cmd[1];
    /* the last trailer's error in the reference's frame, as pushtrain's recorder (step.c) */
    pt_tracking_errors(ref, info->x_n, info->y_n, info->theta_n, errors);
    m->r[R_e_lon] = errors[0];
    m->r[R_e_lat] = errors[1];
    m->r[R_e_theta] = errors[2];
    m->r[R_x_d] = ref->x;
    m->r[R_y_d] = ref->y;
    m->r[R_theta_d] = ref->theta;
    m->r[R_v_d] = ref->v;
    m->r[R_w_d] = ref->w;
    m->r[R_x_e] = info->x_e;
    m->r[R_y_e] = info->y_e;
    m->r[R_theta_e] = info->theta_e;
    for (k = 0; k < CTRL_N; k++) {
        m->r[R_phi_meas + k] = phi_meas[k];
    }
    m->i[I_mode] = info->mode;
    m->i[I_direction] = ref->direction;
    m->b[B_done] = done;
}

/* The goal test of pushtrain's master: the reference has ended and the last trailer is within
 * goal_tolerance [m] and goal_heading_tolerance [rad] of the goal. */
static int at_goal(const CtrlModel *m, double t, const PtControlInfo *info) {
    const double dist = hypot(info->x_n - m->goal[0], info->y_n - m->goal[1]);
    return t >= m->reference.t_end - 1e-12 && dist <= m->r[R_goal_tolerance]
           && fabs(pt_wrap(info->theta_n - m->goal[2])) <= m->r[R_goal_heading_tolerance];
}

int ctrl_model_evaluate(CtrlModel *m, char *msg, size_t len) {
    PtController c;
    PtMeasurement meas;
    PtSample ref;
    PtControlInfo info;
    CtrlMemory next = m->memory;
    double phi_meas[CTRL_N], cmd[2];
    const double t = m->time;
    int status;
    if (m->evaluated) {
        return 1;
    }
    c.model.n = CTRL_N;
    c.model.front = &m->r[R_front];
    c.model.rear = &m->r[R_rear];
    c.k_x = m->r[R_k_x];
    c.k_y = m->r[R_k_y];
    c.k_theta = m->r[R_k_theta];
    c.v_max = m->r[R_v_max];
    c.w_max = m->r[R_w_max];
    c.acc_max = m->r[R_acc_max];
    c.alpha_max = m->r[R_alpha_max];
    c.rest_speed = m->r[R_rest_speed];
    measure_joints(m, &next, phi_meas);
    meas.x0 = m->r[R_x0];
    meas.y0 = m->r[R_y0];
    meas.theta0 = m->r[R_theta0];
    meas.phi = phi_meas;
    meas.has_last = m->b[B_measure_last_pose] ? 1 : 0;
    meas.x_n = m->r[R_x_last];
    meas.y_n = m->r[R_y_last];
    meas.theta_n = m->r[R_theta_last];
    status = pt_instant(&c, &next.state, &m->reference, &m->leader, t, &meas, &ref, cmd, &info);
    if (status != PT_OK) {
        snprintf(msg, len, "no command at t = %.9g s: %s (robot pose %g, %g, %g)", t,
                 law_error(status), meas.x0, meas.y0, meas.theta0);
        return 0;
    }
    next.done = next.done || at_goal(m, t, &info);
    set_outputs(m, &ref, &info, cmd, phi_meas, next.done);
    if (!m->have_next) { /* the first command read at this point is the one the step commits */
        m->next = next;
        m->have_next = true;
    }
    m->evaluated = true;
    return 1;
}

int ctrl_model_step(CtrlModel *m, double t_next, char *msg, size_t len) {
    if (!m->have_next && !ctrl_model_evaluate(m, msg, len)) {
        return 0;
    }
    m->memory = m->next;
    m->time = t_next;
    m->evaluated = false;
    m->have_next = false;
    return 1;
}
