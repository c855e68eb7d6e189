/*
 * The FMI plumbing shared by fmi2.c and fmi3.c (see instance.h). No mutable static state: every
 * instance owns its data.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "instance.h"

#define STATE_MAGIC 0x54524e32u /* "TRN2": state q = x0, y0, v0, w0, theta[0..n] */

#if FMI_VERSION == 3
#define FMI_PREFIX "fmi3"
#define STOP_TIME_SOURCE "fmi3EnterInitializationMode"
#define STEP_MODE_NAME "StepMode"
#define ERROR_MODE_NAME "Error (after an fmi3Error; only fmi3Get{VariableType}, " \
                        "fmi3SetFMUState, fmi3Reset and fmi3FreeInstance are allowed)"
#else
#define FMI_PREFIX "fmi2"
#define STOP_TIME_SOURCE "fmi2SetupExperiment"
#define STEP_MODE_NAME "StepComplete"
#define ERROR_MODE_NAME "Error (after an fmi2Error; only fmi2GetXXX, fmi2SetFMUstate, " \
                        "fmi2Reset and fmi2FreeInstance are allowed)"
#endif

typedef struct {
    unsigned int magic;
    unsigned int size;
    Mode mode;
    ModelData data;
} SavedState;

static const char *const log_categories[] = {"logStatusError", "logStatusWarning", "logDebug"};

/* ---------------------------------------------------------------- life cycle and logging */

Instance *instance_new(size_t size, const char *name, LogSink sink, bool logging_on) {
    Instance *inst = (Instance *)calloc(1, size);
    if (inst == NULL) {
        return NULL;
    }
    inst->instance_name = (char *)malloc(strlen(name) + 1);
    if (inst->instance_name == NULL) {
        free(inst);
        return NULL;
    }
    strcpy(inst->instance_name, name);
    inst->sink = sink;
    inst->logging_on = logging_on;
    inst->log_debug = false;
    inst->log_errors = true;
    inst->log_warnings = true;
    instance_reset(inst);
    return inst;
}

void instance_free(Instance *inst) {
    if (inst == NULL) {
        return;
    }
    free(inst->instance_name);
    free(inst);
}

void instance_reset(Instance *inst) {
    model_set_defaults(&inst->data);
    inst->stop_time_defined = false;
    inst->stop_time = 0.0;
    inst->mode = mode_instantiated;
}

void instance_log(const Instance *inst, Status status, const char *category, const char *fmt,
                  ...) {
    char buffer[MSG_LEN];
    va_list args;
    if (inst == NULL || inst->sink == NULL) {
        return;
    }
    if (status == status_ok && !(inst->logging_on && inst->log_debug)) {
        return;
    }
    if ((status == status_warning || status == status_discard) && !inst->log_warnings) {
        return;
    }
    if (status >= status_error && !inst->log_errors) {
        return;
    }
    va_start(args, fmt);
    vsnprintf(buffer, sizeof(buffer), fmt, args);
    va_end(args);
    inst->sink(inst, status, category, buffer);
}

Status instance_fail(Instance *inst, const char *function, const char *fmt, ...) {
    char buffer[MSG_LEN];
    va_list args;
    va_start(args, fmt);
    vsnprintf(buffer, sizeof(buffer), fmt, args);
    va_end(args);
    instance_log(inst, status_error, "logStatusError", "%s: %s", function, buffer);
    inst->mode = mode_error;
    return status_error;
}

static const char *mode_name(Mode mode) {
    switch (mode) {
    case mode_instantiated: return "Instantiated";
    case mode_configuration: return "ConfigurationMode";
    case mode_initialization: return "InitializationMode";
    case mode_step: return STEP_MODE_NAME;
    case mode_terminated: return "Terminated";
    case mode_error: break;
    }
    return ERROR_MODE_NAME;
}

bool instance_allowed(Instance *inst, const char *function, int modes) {
    if (inst == NULL) {
        return false;
    }
    if (!(inst->mode & modes)) {
        instance_fail(inst, function, "not allowed in mode %s", mode_name(inst->mode));
        return false;
    }
    return true;
}

Status instance_not_supported(Instance *inst, const char *function, const char *why) {
    return (inst == NULL) ? status_error
                          : instance_fail(inst, function, "not supported (%s)", why);
}

Status instance_set_debug_logging(Instance *inst, const char *function, bool logging_on,
                                  size_t n_categories, const char *const categories[]) {
    size_t k;
    inst->logging_on = logging_on;
    if (n_categories == 0) {
        /* loggingOn applies to all categories; errors and warnings are always reported */
        inst->log_debug = logging_on;
        inst->log_errors = true;
        inst->log_warnings = true;
        return status_ok;
    }
    if (categories == NULL) {
        return instance_fail(inst, function, "categories = NULL with nCategories = %u",
                             (unsigned)n_categories);
    }
    for (k = 0; k < n_categories; k++) {
        const char *name = categories[k];
        if (name != NULL && strcmp(name, "logDebug") == 0) {
            inst->log_debug = logging_on;
        } else if (name != NULL && strcmp(name, "logStatusError") == 0) {
            inst->log_errors = logging_on;
        } else if (name != NULL && strcmp(name, "logStatusWarning") == 0) {
            inst->log_warnings = logging_on;
        } else {
            return instance_fail(inst, function, "unknown log category '%s'; allowed: %s, %s, %s",
                                 name ? name : "(null)", log_categories[0], log_categories[1],
                                 log_categories[2]);
        }
    }
    return status_ok;
}

/* ---------------------------------------------------------------- get and set */

static bool setup_mode(const Instance *inst) {
    return inst->mode == mode_instantiated || inst->mode == mode_configuration
           || inst->mode == mode_initialization;
}

static SetPhase set_phase(const Instance *inst) {
    switch (inst->mode) {
    case mode_instantiated: return phase_instantiated;
    case mode_configuration: return phase_configuration;
    case mode_initialization: return phase_initialization;
    case mode_step: case mode_terminated: case mode_error: break;
    }
    return phase_running;
}

/* Makes the outputs current. They are a cache: computed after each step, after the end of
   initialization and at the first read after a set, and kept while outputs_valid, which every set
   clears (setting an input changes F_lat; before initialization ends, setting a parameter or a
   start value changes every output). outputs_valid implies a finite state and finite outputs, so
   a read of current outputs costs O(1) here and O(values) in all; a read after a set costs O(n)
   once. Before initialization ends the outputs follow the (possibly changed) start parameters,
   which must then be valid; after an error with a non-finite state there are none. */
static Status ensure_outputs(Instance *inst, const char *function) {
    char msg[MSG_LEN];
    if (inst->data.outputs_valid) {
        return status_ok;
    }
    if (setup_mode(inst)) {
        if (!model_check_parameters(&inst->data, msg, sizeof(msg))) {
            return instance_fail(inst, function, "outputs cannot be computed: %s", msg);
        }
        model_state_from_start(&inst->data);
    }
    if (!model_state_is_finite(&inst->data)) {
        return instance_fail(inst, function, "the state is non-finite after an error: no outputs");
    }
    model_compute_outputs(&inst->data);
    if (!model_outputs_are_finite(&inst->data)) {
        inst->data.outputs_valid = false;
        return instance_fail(inst, function, "outputs became non-finite at t = %.9g "
                             "(overflow of the forces: velocities %g m/s, %g rad/s of the "
                             "robot)", inst->data.time, inst->data.q[IX_V0],
                             inst->data.q[IX_W0]);
    }
    return status_ok;
}

/* Every value of the call was used: nValues matches the variables' sizes at the current n. */
static Status check_count(Instance *inst, const char *function, size_t nvr, size_t used,
                          size_t n_values) {
    if (used != n_values) {
        return instance_fail(inst, function, "nValues = %u but the %u variable%s hold%s %u "
                             "value%s (n = %d)", (unsigned)n_values, (unsigned)nvr,
                             nvr == 1 ? "" : "s", nvr == 1 ? "s" : "", (unsigned)used,
                             used == 1 ? "" : "s", inst->data.n);
    }
    return status_ok;
}

#define DEFINE_GET(NAME, TYPE, MODEL_GET)                                                       \
    Status NAME(Instance *inst, const char *function, const unsigned vr[], size_t nvr,          \
                TYPE values[], size_t n_values) {                                               \
        char msg[MSG_LEN];                                                                      \
        size_t k, index = 0;                                                                    \
        bool current = false; /* outputs made current in this call: once, at the first */      \
        if (nvr > 0 && (vr == NULL || values == NULL)) {                                        \
            return instance_fail(inst, function, "vr or values is NULL");                       \
        }                                                                                       \
        for (k = 0; k < nvr; k++) {                                                             \
            if (!current && model_needs_outputs(&inst->data, vr[k])) {                          \
                if (ensure_outputs(inst, function) != status_ok) {                              \
                    return status_error;                                                        \
                }                                                                               \
                current = true;                                                                 \
            }                                                                                   \
            if (!MODEL_GET(&inst->data, vr[k], values, n_values, &index, msg, sizeof(msg))) {   \
                return instance_fail(inst, function, "%s", msg);                                \
            }                                                                                   \
        }                                                                                       \
        return check_count(inst, function, nvr, index, n_values);                               \
    }

DEFINE_GET(instance_get_real, double, model_get_real)
DEFINE_GET(instance_get_integer, int, model_get_integer)
DEFINE_GET(instance_get_boolean, bool, model_get_boolean)
DEFINE_GET(instance_get_uint64, uint64_t, model_get_uint64)

#define DEFINE_SET(NAME, TYPE, MODEL_SET)                                                       \
    Status NAME(Instance *inst, const char *function, const unsigned vr[], size_t nvr,          \
                const TYPE values[], size_t n_values) {                                         \
        char msg[MSG_LEN];                                                                      \
        size_t k, index = 0;                                                                    \
        const SetPhase phase = set_phase(inst);                                                 \
        if (nvr > 0 && (vr == NULL || values == NULL)) {                                        \
            return instance_fail(inst, function, "vr or values is NULL");                       \
        }                                                                                       \
        if (nvr > 0) {                                                                          \
            inst->data.outputs_valid = false; /* every set may change the outputs */            \
        }                                                                                       \
        for (k = 0; k < nvr; k++) {                                                             \
            if (!MODEL_SET(&inst->data, vr[k], values, n_values, &index, phase, msg,            \
                           sizeof(msg))) {                                                      \
                return instance_fail(inst, function, "%s", msg);                                \
            }                                                                                   \
        }                                                                                       \
        return check_count(inst, function, nvr, index, n_values);                               \
    }

DEFINE_SET(instance_set_real, double, model_set_real)
DEFINE_SET(instance_set_integer, int, model_set_integer)
DEFINE_SET(instance_set_boolean, bool, model_set_boolean)
DEFINE_SET(instance_set_uint64, uint64_t, model_set_uint64)

/* ---------------------------------------------------------------- initialization and steps */

Status instance_end_configuration(Instance *inst, const char *function) {
    char msg[MSG_LEN];
    if (!model_check_structure(&inst->data, msg, sizeof(msg))) {
        return instance_fail(inst, function, "%s", msg);
    }
    return status_ok;
}

Status instance_exit_initialization(Instance *inst, const char *function) {
    char msg[MSG_LEN];
    ModelData *m = &inst->data;
    /* Parameters may have been set after entering initialization (FMIL-based importers):
       everything is derived from them here. */
    if (!model_check_parameters(m, msg, sizeof(msg))
        || !model_check_combinations(m, msg, sizeof(msg))) {
        return instance_fail(inst, function, "%s", msg);
    }
    model_state_from_start(m);
    model_compute_outputs(m);
    if (!model_outputs_are_finite(m)) {
        m->outputs_valid = false;
        return instance_fail(inst, function, "the start values give non-finite outputs "
                             "(v_start = %g, w_start = %g, v_cmd = %g, w_cmd = %g)", m->v_start,
                             m->w_start, m->v_cmd, m->w_cmd);
    }
    inst->mode = mode_step;
    return status_ok;
}

Status instance_do_step(Instance *inst, const char *function, double t, double h) {
    ModelData *m = &inst->data;
    double tolerance;
    if (!(h > 0.0) || !isfinite(h)) {
        return instance_fail(inst, function, "communicationStepSize = %g: must be finite and > 0",
                             h);
    }
    if (h / m->max_substep > 1e9) {
        return instance_fail(inst, function, "communicationStepSize = %g s needs more than 1e9 "
                             "substeps of max_substep = %g s", h, m->max_substep);
    }
    /* Importers accumulate times differently (sums of floats, integer nanoseconds). */
    tolerance = 1e-9 + 1e-12 * fabs(m->time);
    if (!isfinite(t) || fabs(t - m->time) > tolerance) {
        return instance_fail(inst, function, "currentCommunicationPoint = %.17g differs from the "
                             "FMU's time %.17g", t, m->time);
    }
    if (inst->stop_time_defined && t + h > inst->stop_time + tolerance) {
        return instance_fail(inst, function, "the step from t = %.17g by %.17g s ends after "
                             "stopTime = %.17g (set in " STOP_TIME_SOURCE ")", t, h,
                             inst->stop_time);
    }
    m->time = t;
    if (inst->log_debug && inst->logging_on) {
        instance_log(inst, status_ok, "logDebug", "%s: t = %.9g, h = %.9g", function, t, h);
    }
    model_integrate(m, h, t + h);
    if (model_state_is_finite(m)) {
        model_compute_outputs(m); /* outputs of the new point, checked once here */
    }
    if (!model_state_is_finite(m) || !model_outputs_are_finite(m)) {
        m->outputs_valid = false; /* a later read fails instead of returning them */
        return instance_fail(inst, function, "the state or outputs became non-finite in the step "
                             "from t = %.9g to %.9g (inputs v_cmd = %g, w_cmd = %g)", t, t + h,
                             m->v_cmd, m->w_cmd);
    }
    return status_ok;
}

/* ---------------------------------------------------------------- FMU states */

Status instance_get_state(Instance *inst, const char *function, void **state) {
    SavedState *saved;
    if (state == NULL) {
        return instance_fail(inst, function, "FMUstate is NULL");
    }
    saved = (SavedState *)*state;
    if (saved == NULL) {
        saved = (SavedState *)calloc(1, sizeof(SavedState));
        if (saved == NULL) {
            return instance_fail(inst, function, "out of memory");
        }
    }
    saved->magic = STATE_MAGIC;
    saved->size = (unsigned int)sizeof(SavedState);
    saved->mode = inst->mode;
    saved->data = inst->data;
    *state = saved;
    return status_ok;
}

Status instance_set_state(Instance *inst, const char *function, const void *state) {
    const SavedState *saved = (const SavedState *)state;
    if (saved == NULL || saved->magic != STATE_MAGIC || saved->size != sizeof(SavedState)) {
        return instance_fail(inst, function, "FMUstate is NULL or not a TrailerTrain state of "
                             "this build (n = %d)", inst->data.n);
    }
    inst->data = saved->data;
    inst->mode = saved->mode;
    return status_ok;
}

Status instance_free_state(Instance *inst, const char *function, void **state) {
    (void)inst;
    (void)function;
    if (state != NULL) {
        free(*state);
        *state = NULL;
    }
    return status_ok;
}

Status instance_state_size(Instance *inst, const char *function, size_t *size) {
    if (size == NULL) {
        return instance_fail(inst, function, "size is NULL");
    }
    *size = sizeof(SavedState);
    return status_ok;
}

Status instance_serialize_state(Instance *inst, const char *function, const void *state,
                                unsigned char *bytes, size_t size) {
    if (state == NULL || bytes == NULL || size < sizeof(SavedState)) {
        return instance_fail(inst, function, "need a state and a buffer of %u bytes, got %u",
                             (unsigned)sizeof(SavedState), (unsigned)size);
    }
    memcpy(bytes, state, sizeof(SavedState));
    return status_ok;
}

Status instance_deserialize_state(Instance *inst, const char *function,
                                  const unsigned char *bytes, size_t size, void **state) {
    SavedState header;
    SavedState *saved;
    if (bytes == NULL || state == NULL || size != sizeof(SavedState)) {
        return instance_fail(inst, function, "serialized state has %u bytes; this build "
                             "(" FMI_PREFIX ", up to %d trailers) expects %u", (unsigned)size,
                             MAX_TRAILERS, (unsigned)sizeof(SavedState));
    }
    memcpy(&header, bytes, sizeof(SavedState));
    if (header.magic != STATE_MAGIC || header.size != sizeof(SavedState)) {
        return instance_fail(inst, function, "not a TrailerTrain state of this build");
    }
    saved = (SavedState *)*state;
    if (saved == NULL) {
        saved = (SavedState *)malloc(sizeof(SavedState));
        if (saved == NULL) {
            return instance_fail(inst, function, "out of memory");
        }
    }
    *saved = header;
    *state = saved;
    return status_ok;
}
