/*
 * The BackwardController's side of the glue's model interface (fmu_model.h): its variables by
 * value reference (the table ctrl_vars of the generated ctrl_variables.h), what can be set when,
 * the mission table from the resources, the communication points. The law and its memory are
 * ctrl_model.c.
 *
 * Parameters may be set before or after entering initialization (FMIL-based importers set them
 * after) and are checked when it ends. Inputs must be finite (as the plant's).
 */
#include <math.h>
#include <stdio.h>

#include "ctrl_instance.h"

#define PATH_LEN 4096

/* ---------------------------------------------------------------- life cycle and step */

bool model_instantiate(ModelData *m, const char *resource_location, char *msg, size_t len) {
    char path[PATH_LEN];
    if (!ctrl_resource_path(resource_location, CTRL_TABLE_FILE, path, sizeof(path), msg, len)) {
        return false;
    }
    if (!ctrl_table_load(path, &m->table, msg, len)
        || !ctrl_model_init(&m->model, &m->table, msg, len)) {
        ctrl_table_free(&m->table);
        return false;
    }
    return true;
}

void model_free(ModelData *m) {
    ctrl_model_free(&m->model);
    ctrl_table_free(&m->table);
}

void model_set_defaults(ModelData *m) {
    ctrl_model_set_defaults(&m->model);
    m->start_time = 0.0;
    m->steps = 0;
}

void model_set_start_time(ModelData *m, double start_time) {
    m->model.time = start_time;
    m->start_time = start_time;
    m->steps = 0;
    ctrl_model_start(&m->model);
}

double model_time(const ModelData *m) {
    return m->model.time;
}

bool model_exit_initialization(ModelData *m, char *msg, size_t len) {
    if (!ctrl_model_check_parameters(&m->model, msg, len)) {
        return false;
    }
    ctrl_model_start(&m->model);
    return true;
}

bool model_do_step(ModelData *m, double t, double h, double tolerance, char *msg, size_t len) {
    double t_next;
    if (m->steps == 0) {
        m->step_size = h;
    }
    t_next = m->start_time + (double)(m->steps + 1) * m->step_size;
    if (m->steps >= 0 && fabs(t + h - t_next) <= tolerance) {
        m->steps++; /* on the grid of the first step (masters jitter h by an ulp) */
    } else {
        m->steps = -1; /* variable steps from here on */
        t_next = t + h;
    }
    return ctrl_model_step(&m->model, t_next, msg, len) != 0;
}

/* ---------------------------------------------------------------- outputs */

static const CtrlVarInfo *find(unsigned vr) {
    const CtrlVarInfo *v = (vr < CTRL_VR_END) ? &ctrl_vars[vr] : NULL;
    return (v == NULL || v->name == NULL) ? NULL : v;
}

bool model_needs_outputs(const ModelData *m, unsigned vr) {
    const CtrlVarInfo *v = find(vr);
    (void)m;
    return v != NULL && v->causality == ctrl_output;
}

/* The outputs are evaluated at the first read after the inputs or the time changed (see
   ctrl_model.h); after an error a read returns the last values, for diagnostics. Before
   initialization ends the parameters must already be valid. */
bool model_update_outputs(ModelData *m, ModelPhase phase, char *msg, size_t len) {
    char why[CTRL_MSG_LEN];
    if (phase == phase_error) {
        return true;
    }
    if (phase <= phase_initialization
        && !ctrl_model_check_parameters(&m->model, why, sizeof(why))) {
        snprintf(msg, len, "outputs cannot be computed: %s", why);
        return false;
    }
    return ctrl_model_evaluate(&m->model, msg, len) != 0;
}

/* ---------------------------------------------------------------- get and set */

/* The variable of value reference vr, of the given type; NULL with a message if there is none. */
static const CtrlVarInfo *lookup(unsigned vr, CtrlType type, char *msg, size_t len) {
    static const char *const type_names[] = {"Real", "Integer", "Boolean"};
    const CtrlVarInfo *v = find(vr);
    if (v == NULL) {
        snprintf(msg, len, "value reference %u: no such variable", vr);
        return NULL;
    }
    if (v->type != type) {
        snprintf(msg, len, "%s (value reference %u) is a %s variable, not %s", v->name, vr,
                 type_names[v->type], type_names[type]);
        return NULL;
    }
    return v;
}

/* values[*index] exists (every variable holds one value). */
static bool room(size_t n_values, size_t index, char *msg, size_t len) {
    if (index >= n_values) {
        snprintf(msg, len, "more variables than the %u values given", (unsigned)n_values);
        return false;
    }
    return true;
}

bool model_get_reals(const ModelData *m, const unsigned vr[], size_t nvr, double values[],
                     size_t n_values, size_t *index, char *msg, size_t len) {
    size_t k;
    for (k = 0; k < nvr; k++) {
        const CtrlVarInfo *v = lookup(vr[k], ctrl_real, msg, len);
        if (v == NULL || !room(n_values, *index, msg, len)) {
            return false;
        }
        values[(*index)++] = m->model.r[v->offset];
    }
    return true;
}

bool model_get_integer(const ModelData *m, unsigned vr, int values[], size_t n_values,
                       size_t *index, char *msg, size_t len) {
    const CtrlVarInfo *v = lookup(vr, ctrl_integer, msg, len);
    if (v == NULL || !room(n_values, *index, msg, len)) {
        return false;
    }
    values[(*index)++] = m->model.i[v->offset];
    return true;
}

bool model_get_boolean(const ModelData *m, unsigned vr, bool values[], size_t n_values,
                       size_t *index, char *msg, size_t len) {
    const CtrlVarInfo *v = lookup(vr, ctrl_boolean, msg, len);
    if (v == NULL || !room(n_values, *index, msg, len)) {
        return false;
    }
    values[(*index)++] = m->model.b[v->offset] != 0;
    return true;
}

static const char *phase_name(ModelPhase phase) {
    switch (phase) {
    case phase_running: return "StepComplete";
    case phase_terminated: return "Terminated";
    default: break;
    }
    return "Error";
}

/* Parameters before initialization ends, inputs in any mode but Terminated; every value of a
   Real must be finite. */
static bool check_set(const CtrlVarInfo *v, double value, ModelPhase phase, char *msg,
                      size_t len) {
    if (v->causality == ctrl_output || v->causality == ctrl_calculated_parameter) {
        snprintf(msg, len, "%s is an %s: it cannot be set", v->name,
                 v->causality == ctrl_output ? "output" : "calculated parameter");
        return false;
    }
    if (v->causality == ctrl_parameter && phase > phase_initialization) {
        snprintf(msg, len, "parameter %s cannot be set in mode %s (fixed after initialization)",
                 v->name, phase_name(phase));
        return false;
    }
    if (v->causality == ctrl_input && phase >= phase_terminated) {
        snprintf(msg, len, "input %s cannot be set after fmi2Terminate", v->name);
        return false;
    }
    if (!isfinite(value)) {
        snprintf(msg, len, "%s %s = %g: must be finite",
                 v->causality == ctrl_input ? "input" : "parameter", v->name, value);
        return false;
    }
    return true;
}

/* After a set: a parameter restarts the memory (it follows v_start, w_start, dt_start), an input
   makes the outputs stale. */
static void changed(ModelData *m, const CtrlVarInfo *v) {
    if (v->causality == ctrl_parameter) {
        ctrl_model_start(&m->model);
    } else {
        m->model.evaluated = false;
    }
}

bool model_set_real(ModelData *m, unsigned vr, const double values[], size_t n_values,
                    size_t *index, ModelPhase phase, char *msg, size_t len) {
    const CtrlVarInfo *v = lookup(vr, ctrl_real, msg, len);
    if (v == NULL || !room(n_values, *index, msg, len)
        || !check_set(v, values[*index], phase, msg, len)) {
        return false;
    }
    m->model.r[v->offset] = values[(*index)++];
    changed(m, v);
    return true;
}

bool model_set_integer(ModelData *m, unsigned vr, const int values[], size_t n_values,
                       size_t *index, ModelPhase phase, char *msg, size_t len) {
    const CtrlVarInfo *v = lookup(vr, ctrl_integer, msg, len);
    if (v == NULL || !room(n_values, *index, msg, len)
        || !check_set(v, (double)values[*index], phase, msg, len)) {
        return false;
    }
    m->model.i[v->offset] = values[(*index)++];
    changed(m, v);
    return true;
}

bool model_set_boolean(ModelData *m, unsigned vr, const bool values[], size_t n_values,
                       size_t *index, ModelPhase phase, char *msg, size_t len) {
    const CtrlVarInfo *v = lookup(vr, ctrl_boolean, msg, len);
    if (v == NULL || !room(n_values, *index, msg, len) || !check_set(v, 0.0, phase, msg, len)) {
        return false;
    }
    m->model.b[v->offset] = values[(*index)++] ? 1 : 0;
    changed(m, v);
    return true;
}
