/*
 * The FMI plumbing shared by fmi2.c and fmi3.c over any model of fmu_model.h (see instance.h).
 * No mutable static state: every instance owns its data.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "instance.h"

#define STATE_MAGIC 0x54524e32u /* "TRN2": the layout of a saved ModelData */

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

Instance *instance_new(size_t size, const char *name, const char *resource_location,
                       LogSink sink, bool logging_on, char *msg, size_t len) {
    Instance *inst = (Instance *)calloc(1, size);
    if (inst == NULL || (inst->instance_name = (char *)malloc(strlen(name) + 1)) == NULL) {
        free(inst);
        snprintf(msg, len, "out of memory");
        return NULL;
    }
    strcpy(inst->instance_name, name);
    if (!model_instantiate(&inst->data, resource_location, msg, len)) { /* released its own */
        free(inst->instance_name);
        free(inst);
        return NULL;
    }
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
    model_free(&inst->data);
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

static ModelPhase model_phase(const Instance *inst) {
    switch (inst->mode) {
    case mode_instantiated: return phase_instantiated;
    case mode_configuration: return phase_configuration;
    case mode_initialization: return phase_initialization;
    case mode_step: return phase_running;
    case mode_terminated: return phase_terminated;
    case mode_error: break;
    }
    return phase_error;
}

/* Makes the outputs current (the model keeps them as a cache: see model_update_outputs). */
static Status ensure_outputs(Instance *inst, const char *function) {
    char msg[MSG_LEN];
    if (!model_update_outputs(&inst->data, model_phase(inst), msg, sizeof(msg))) {
        return instance_fail(inst, function, "%s", msg);
    }
    return status_ok;
}

/* Every value of the call was used: nValues matches the variables' sizes at the current n. */
static Status check_count(Instance *inst, const char *function, size_t nvr, size_t used,
                          size_t n_values) {
    if (used != n_values) {
#if FMI_VERSION == 3 /* FMI 3.0 arrays: their sizes follow the plant's structural parameter n */
        return instance_fail(inst, function, "nValues = %u but the %u variable%s hold%s %u "
                             "value%s (n = %d)", (unsigned)n_values, (unsigned)nvr,
                             nvr == 1 ? "" : "s", nvr == 1 ? "s" : "", (unsigned)used,
                             used == 1 ? "" : "s", inst->data.n);
#else /* one value per scalar variable */
        return instance_fail(inst, function, "nValues = %u but the %u variable%s hold%s %u "
                             "value%s", (unsigned)n_values, (unsigned)nvr, nvr == 1 ? "" : "s",
                             nvr == 1 ? "s" : "", (unsigned)used, used == 1 ? "" : "s");
#endif
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

Status instance_get_real(Instance *inst, const char *function, const unsigned vr[], size_t nvr,
                         double values[], size_t n_values) {
    char msg[MSG_LEN];
    size_t k, index = 0;
    if (nvr > 0 && (vr == NULL || values == NULL)) {
        return instance_fail(inst, function, "vr or values is NULL");
    }
    for (k = 0; k < nvr && !model_needs_outputs(&inst->data, vr[k]); k++) {
    } /* the outputs are made current once if the call reads one (a read of outputs: k = 0) */
    if (k < nvr && ensure_outputs(inst, function) != status_ok) {
        return status_error;
    }
    if (!model_get_reals(&inst->data, vr, nvr, values, n_values, &index, msg, sizeof(msg))) {
        return instance_fail(inst, function, "%s", msg);
    }
    return check_count(inst, function, nvr, index, n_values);
}

DEFINE_GET(instance_get_integer, int, model_get_integer)
DEFINE_GET(instance_get_boolean, bool, model_get_boolean)
#if FMI_VERSION == 3
DEFINE_GET(instance_get_uint64, uint64_t, model_get_uint64)
#endif

#define DEFINE_SET(NAME, TYPE, MODEL_SET)                                                       \
    Status NAME(Instance *inst, const char *function, const unsigned vr[], size_t nvr,          \
                const TYPE values[], size_t n_values) {                                         \
        char msg[MSG_LEN];                                                                      \
        size_t k, index = 0;                                                                    \
        const ModelPhase phase = model_phase(inst);                                             \
        if (nvr > 0 && (vr == NULL || values == NULL)) {                                        \
            return instance_fail(inst, function, "vr or values is NULL");                       \
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
#if FMI_VERSION == 3
DEFINE_SET(instance_set_uint64, uint64_t, model_set_uint64)
#endif

/* ---------------------------------------------------------------- initialization and steps */

#if FMI_VERSION == 3
Status instance_end_configuration(Instance *inst, const char *function) {
    char msg[MSG_LEN];
    if (!model_check_structure(&inst->data, msg, sizeof(msg))) {
        return instance_fail(inst, function, "%s", msg);
    }
    return status_ok;
}
#endif

Status instance_exit_initialization(Instance *inst, const char *function) {
    char msg[MSG_LEN];
    if (!model_exit_initialization(&inst->data, msg, sizeof(msg))) {
        return instance_fail(inst, function, "%s", msg);
    }
    inst->mode = mode_step;
    return status_ok;
}

Status instance_do_step(Instance *inst, const char *function, double t, double h) {
    char msg[MSG_LEN];
    const double now = model_time(&inst->data);
    /* Importers accumulate times differently (sums of floats, integer nanoseconds). */
    const double tolerance = 1e-9 + 1e-12 * fabs(now);
    if (!(h > 0.0) || !isfinite(h)) {
        return instance_fail(inst, function, "communicationStepSize = %g: must be finite and > 0",
                             h);
    }
    if (!isfinite(t) || fabs(t - now) > tolerance) {
        return instance_fail(inst, function, "currentCommunicationPoint = %.17g differs from the "
                             "FMU's time %.17g", t, now);
    }
    if (inst->stop_time_defined && t + h > inst->stop_time + tolerance) {
        return instance_fail(inst, function, "the step from t = %.17g by %.17g s ends after "
                             "stopTime = %.17g (set in " STOP_TIME_SOURCE ")", t, h,
                             inst->stop_time);
    }
    if (inst->log_debug && inst->logging_on) {
        instance_log(inst, status_ok, "logDebug", "%s: t = %.9g, h = %.9g", function, t, h);
    }
    if (!model_do_step(&inst->data, t, h, tolerance, msg, sizeof(msg))) {
        return instance_fail(inst, function, "%s", msg);
    }
    return status_ok;
}

/* ---------------------------------------------------------------- FMU states */

#define STATES_PROVIDED(inst, function, flag)                                                   \
    if (!MODEL_CAN_GET_AND_SET_STATE) {                                                         \
        return instance_not_supported((inst), (function), flag " = false");                     \
    }

Status instance_get_state(Instance *inst, const char *function, void **state) {
    SavedState *saved;
    STATES_PROVIDED(inst, function, "canGetAndSetFMUstate");
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
    STATES_PROVIDED(inst, function, "canGetAndSetFMUstate");
    if (saved == NULL || saved->magic != STATE_MAGIC || saved->size != sizeof(SavedState)) {
        return instance_fail(inst, function, "FMUstate is NULL or not a " MODEL_IDENTIFIER
                             " state of this build");
    }
    inst->data = saved->data;
    inst->mode = saved->mode;
    return status_ok;
}

Status instance_free_state(Instance *inst, const char *function, void **state) {
    STATES_PROVIDED(inst, function, "canGetAndSetFMUstate");
    if (state != NULL) {
        free(*state);
        *state = NULL;
    }
    return status_ok;
}

Status instance_state_size(Instance *inst, const char *function, size_t *size) {
    STATES_PROVIDED(inst, function, "canSerializeFMUstate");
    if (size == NULL) {
        return instance_fail(inst, function, "size is NULL");
    }
    *size = sizeof(SavedState);
    return status_ok;
}

Status instance_serialize_state(Instance *inst, const char *function, const void *state,
                                unsigned char *bytes, size_t size) {
    STATES_PROVIDED(inst, function, "canSerializeFMUstate");
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
    STATES_PROVIDED(inst, function, "canSerializeFMUstate");
    if (bytes == NULL || state == NULL || size != sizeof(SavedState)) {
        return instance_fail(inst, function, "serialized state has %u bytes; this build "
                             "(" FMI_PREFIX ") expects %u", (unsigned)size,
                             (unsigned)sizeof(SavedState));
    }
    memcpy(&header, bytes, sizeof(SavedState));
    if (header.magic != STATE_MAGIC || header.size != sizeof(SavedState)) {
        return instance_fail(inst, function, "not a " MODEL_IDENTIFIER " state of this build");
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
