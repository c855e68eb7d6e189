/*
 * FMI 2.0 Co-Simulation interface of TrailerTrain, written from the FMI 2.0.x specification.
 *
 * Only the fmi2* functions are exported (the headers come from the importing tool, e.g. fmpy);
 * everything else is static or hidden. No mutable static state: every instance owns its data.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "model.h"

typedef enum {
    mode_instantiated = 1,
    mode_initialization = 2,
    mode_step_complete = 4,
    mode_terminated = 8,
    mode_error = 16
} Mode;

#define SETUP_MODES (mode_instantiated | mode_initialization)
#define ANY_MODE (SETUP_MODES | mode_step_complete | mode_terminated)
/* FMI 2.0: after a function returned fmi2Error the instance is in the error state; then only
   fmi2GetXXX (for diagnostics), fmi2SetFMUstate (restart from a saved state), fmi2FreeFMUstate,
   fmi2Reset and fmi2FreeInstance are allowed (and fmi2SetDebugLogging). */
#define ERROR_MODES (ANY_MODE | mode_error)
#define MSG_LEN 512
#define STATE_MAGIC 0x54524e32u /* "TRN2": state q = x0, y0, v0, w0, theta[0..n] */

typedef struct {
    ModelData data;
    Mode mode;
    bool stop_time_defined; /* from fmi2SetupExperiment: no step may end after stop_time */
    double stop_time;
    char *instance_name;
    fmi2CallbackFunctions callbacks;
    fmi2Boolean logging_on;
    fmi2Boolean log_debug;   /* category logDebug */
    fmi2Boolean log_errors;  /* category logStatusError */
    fmi2Boolean log_warnings;
} Instance;

typedef struct {
    unsigned int magic;
    unsigned int size;
    Mode mode;
    ModelData data;
} SavedState;

static const char *const log_categories[] = {"logStatusError", "logStatusWarning", "logDebug"};

static void log_message(const Instance *inst, fmi2Status status, const char *category,
                        const char *fmt, ...) {
    char buffer[MSG_LEN];
    va_list args;
    if (inst == NULL || inst->callbacks.logger == NULL) {
        return;
    }
    if (status == fmi2OK && !(inst->logging_on && inst->log_debug)) {
        return;
    }
    if ((status == fmi2Warning || status == fmi2Discard) && !inst->log_warnings) {
        return;
    }
    if (status >= fmi2Error && !inst->log_errors) {
        return;
    }
    va_start(args, fmt);
    vsnprintf(buffer, sizeof(buffer), fmt, args);
    va_end(args);
    /* The logger interprets '#' as a value-reference escape: avoid it in messages. */
    inst->callbacks.logger(inst->callbacks.componentEnvironment, inst->instance_name, status,
                           category, "%s", buffer);
}

/* Logs "function: message", moves the instance to the error state and returns fmi2Error. */
static fmi2Status fail(Instance *inst, const char *function, const char *fmt, ...) {
    char buffer[MSG_LEN];
    va_list args;
    va_start(args, fmt);
    vsnprintf(buffer, sizeof(buffer), fmt, args);
    va_end(args);
    log_message(inst, fmi2Error, "logStatusError", "%s: %s", function, buffer);
    inst->mode = mode_error;
    return fmi2Error;
}

static const char *mode_name(Mode mode) {
    switch (mode) {
    case mode_instantiated: return "Instantiated";
    case mode_initialization: return "InitializationMode";
    case mode_step_complete: return "StepComplete";
    case mode_terminated: return "Terminated";
    case mode_error: break;
    }
    return "Error (after an fmi2Error; only fmi2GetXXX, fmi2SetFMUstate, fmi2Reset and "
           "fmi2FreeInstance are allowed)";
}

/* Guard: c is an instance and the call is allowed in its mode (else logged: an error). */
static bool allowed(Instance *inst, const char *function, int modes) {
    if (inst == NULL) {
        return false;
    }
    if (!(inst->mode & modes)) {
        fail(inst, function, "not allowed in mode %s", mode_name(inst->mode));
        return false;
    }
    return true;
}

/*
 * Every fmi2 function that takes an instance starts with BEGIN(modes): the guard above, naming the
 * function by __func__. FAIL(...) logs "function: message", moves the instance to the error state
 * and returns fmi2Error; END returns the call's status (fmi2OK unless set otherwise).
 */
#define BEGIN(modes)                                                                            \
    Instance *const inst = (Instance *)c;                                                       \
    fmi2Status status = fmi2OK;                                                                 \
    if (!allowed(inst, __func__, (modes))) {                                                    \
        return fmi2Error;                                                                       \
    }
#define FAIL(...) return fail(inst, __func__, __VA_ARGS__)
#define END return status

/* A function whose capability flag in the XML says it is not provided: calling it is an error. */
static fmi2Status not_supported(fmi2Component c, const char *function, const char *why) {
    return (c == NULL) ? fmi2Error : fail((Instance *)c, function, "not supported (%s)", why);
}

static bool setup_mode(const Instance *inst) {
    return inst->mode == mode_instantiated || inst->mode == mode_initialization;
}

/* Makes the outputs current: O(n), so the getters call it at most once per call. Before
   initialization ends the outputs follow the (possibly changed) start parameters, which must then
   be valid; after an error with a non-finite state there are none. */
static fmi2Status ensure_outputs(Instance *inst, const char *function) {
    char msg[MSG_LEN];
    if (setup_mode(inst)) {
        if (!model_check_parameters(&inst->data, msg, sizeof(msg))) {
            return fail(inst, function, "outputs cannot be computed: %s", msg);
        }
        model_state_from_start(&inst->data);
    }
    if (!model_state_is_finite(&inst->data)) {
        return fail(inst, function, "the state is non-finite after an error: no outputs");
    }
    if (!inst->data.outputs_valid) {
        model_compute_outputs(&inst->data);
        if (!model_outputs_are_finite(&inst->data)) {
            inst->data.outputs_valid = false;
            return fail(inst, function, "outputs became non-finite at t = %.9g (overflow of "
                        "the forces: velocities %g m/s, %g rad/s of the robot)",
                        inst->data.time, inst->data.q[IX_V0], inst->data.q[IX_W0]);
        }
    }
    return fmi2OK;
}

/* ---------------------------------------------------------------- common functions */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    size_t k;
    BEGIN(ERROR_MODES);
    inst->logging_on = loggingOn;
    if (nCategories == 0) {
        /* loggingOn applies to all categories; errors and warnings are always reported */
        inst->log_debug = loggingOn;
        inst->log_errors = fmi2True;
        inst->log_warnings = fmi2True;
        END;
    }
    if (categories == NULL) {
        FAIL("categories = NULL with nCategories = %u", (unsigned)nCategories);
    }
    for (k = 0; k < nCategories; k++) {
        const char *name = categories[k];
        if (name != NULL && strcmp(name, "logDebug") == 0) {
            inst->log_debug = loggingOn;
        } else if (name != NULL && strcmp(name, "logStatusError") == 0) {
            inst->log_errors = loggingOn;
        } else if (name != NULL && strcmp(name, "logStatusWarning") == 0) {
            inst->log_warnings = loggingOn;
        } else {
            FAIL("unknown log category '%s'; allowed: %s, %s, %s", name ? name : "(null)",
                 log_categories[0], log_categories[1], log_categories[2]);
        }
    }
    END;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    Instance *inst;
    const char *name = instanceName ? instanceName : "TrailerTrain";
    (void)fmuResourceLocation; /* no resources are needed; any file: spelling is accepted */
    (void)visible;
    if (functions == NULL || functions->logger == NULL) {
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                          "%s: fmuType = %d: TrailerTrain supports only fmi2CoSimulation (%d)",
                          __func__, (int)fmuType, (int)fmi2CoSimulation);
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, MODEL_GUID) != 0) {
        functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                          "%s: GUID '%s' does not match this binary's '%s' (the "
                          "modelDescription.xml belongs to another build)", __func__,
                          fmuGUID ? fmuGUID : "(null)", MODEL_GUID);
        return NULL;
    }
    inst = (Instance *)calloc(1, sizeof(Instance));
    if (inst == NULL) {
        functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                          "%s: out of memory", __func__);
        return NULL;
    }
    inst->instance_name = (char *)malloc(strlen(name) + 1);
    if (inst->instance_name == NULL) {
        free(inst);
        return NULL;
    }
    strcpy(inst->instance_name, name);
    memcpy(&inst->callbacks, functions, sizeof(fmi2CallbackFunctions));
    inst->logging_on = loggingOn;
    inst->log_debug = fmi2False;
    inst->log_errors = fmi2True;
    inst->log_warnings = fmi2True;
    inst->mode = mode_instantiated;
    inst->stop_time_defined = false;
    model_set_defaults(&inst->data);
    return inst;
}

void fmi2FreeInstance(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (inst == NULL) {
        return;
    }
    free(inst->instance_name);
    free(inst);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    BEGIN(mode_instantiated);
    (void)toleranceDefined; /* fixed substeps: no tolerance to honour */
    (void)tolerance;
    if (!isfinite(startTime)) {
        FAIL("startTime = %g: must be finite", startTime);
    }
    if (stopTimeDefined && !(stopTime >= startTime)) {
        FAIL("stopTime = %g: must be >= startTime = %g", stopTime, startTime);
    }
    inst->data.time = startTime;
    inst->stop_time_defined = stopTimeDefined != fmi2False;
    inst->stop_time = stopTime;
    END;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    BEGIN(mode_instantiated);
    inst->mode = mode_initialization;
    END;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    char msg[MSG_LEN];
    BEGIN(mode_initialization);
    /* Parameters may have been set after fmi2EnterInitializationMode (FMIL-based importers):
       everything is derived from them here. */
    if (!model_check_parameters(&inst->data, msg, sizeof(msg))
        || !model_check_combinations(&inst->data, msg, sizeof(msg))) {
        FAIL("%s", msg);
    }
    model_state_from_start(&inst->data);
    model_compute_outputs(&inst->data);
    if (!model_outputs_are_finite(&inst->data)) {
        FAIL("the start values give non-finite outputs (v_start = %g, w_start = %g, v_cmd = %g, "
             "w_cmd = %g)", inst->data.v_start, inst->data.w_start, inst->data.v_cmd,
             inst->data.w_cmd);
    }
    inst->mode = mode_step_complete;
    END;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    BEGIN(mode_step_complete);
    inst->mode = mode_terminated;
    END;
}

fmi2Status fmi2Reset(fmi2Component c) {
    BEGIN(ERROR_MODES);
    model_set_defaults(&inst->data);
    inst->stop_time_defined = false;
    inst->mode = mode_instantiated;
    END;
}

/* ---------------------------------------------------------------- get */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    char msg[MSG_LEN];
    size_t k;
    bool current = false; /* outputs made current in this call: once, at the first output */
    BEGIN(ERROR_MODES);
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        FAIL("vr or value is NULL");
    }
    for (k = 0; k < nvr; k++) {
        if (!current && model_needs_outputs(&inst->data, vr[k])) {
            if (ensure_outputs(inst, __func__) != fmi2OK) {
                return fmi2Error;
            }
            current = true;
        }
        if (!model_get_real(&inst->data, vr[k], &value[k], msg, sizeof(msg))) {
            FAIL("%s", msg);
        }
    }
    END;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    char msg[MSG_LEN];
    size_t k;
    BEGIN(ERROR_MODES);
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        FAIL("vr or value is NULL");
    }
    for (k = 0; k < nvr; k++) {
        int v;
        if (!model_get_integer(&inst->data, vr[k], &v, msg, sizeof(msg))) {
            FAIL("%s", msg);
        }
        value[k] = v;
    }
    END;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    char msg[MSG_LEN];
    size_t k;
    bool current = false;
    BEGIN(ERROR_MODES);
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        FAIL("vr or value is NULL");
    }
    for (k = 0; k < nvr; k++) {
        bool v;
        if (!current && model_needs_outputs(&inst->data, vr[k])) {
            if (ensure_outputs(inst, __func__) != fmi2OK) {
                return fmi2Error;
            }
            current = true;
        }
        if (!model_get_boolean(&inst->data, vr[k], &v, msg, sizeof(msg))) {
            FAIL("%s", msg);
        }
        value[k] = v ? fmi2True : fmi2False;
    }
    END;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    BEGIN(ERROR_MODES);
    (void)value;
    if (nvr > 0) {
        FAIL("value reference %u: TrailerTrain has no String variables",
             (unsigned)(vr ? vr[0] : 0));
    }
    END;
}

/* ---------------------------------------------------------------- set */

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    char msg[MSG_LEN];
    size_t k;
    BEGIN(SETUP_MODES | mode_step_complete);
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        FAIL("vr or value is NULL");
    }
    for (k = 0; k < nvr; k++) {
        if (!model_set_real(&inst->data, vr[k], value[k], setup_mode(inst), msg, sizeof(msg))) {
            FAIL("%s", msg);
        }
    }
    END;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    char msg[MSG_LEN];
    size_t k;
    BEGIN(SETUP_MODES);
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        FAIL("vr or value is NULL");
    }
    for (k = 0; k < nvr; k++) {
        if (!model_set_integer(&inst->data, vr[k], value[k], setup_mode(inst), msg,
                               sizeof(msg))) {
            FAIL("%s", msg);
        }
    }
    END;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    char msg[MSG_LEN];
    size_t k;
    BEGIN(ANY_MODE);
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        FAIL("vr or value is NULL");
    }
    for (k = 0; k < nvr; k++) {
        if (!model_set_boolean(&inst->data, vr[k], value[k] != fmi2False, setup_mode(inst), msg,
                               sizeof(msg))) {
            FAIL("%s", msg);
        }
    }
    END;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    BEGIN(ANY_MODE);
    (void)value;
    if (nvr > 0) {
        FAIL("value reference %u: TrailerTrain has no String variables",
             (unsigned)(vr ? vr[0] : 0));
    }
    END;
}

/* ---------------------------------------------------------------- FMU state */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    SavedState *saved;
    BEGIN(ANY_MODE);
    if (FMUstate == NULL) {
        FAIL("FMUstate is NULL");
    }
    saved = (SavedState *)*FMUstate;
    if (saved == NULL) {
        saved = (SavedState *)calloc(1, sizeof(SavedState));
        if (saved == NULL) {
            FAIL("out of memory");
        }
    }
    saved->magic = STATE_MAGIC;
    saved->size = (unsigned int)sizeof(SavedState);
    saved->mode = inst->mode;
    saved->data = inst->data;
    *FMUstate = saved;
    END;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    const SavedState *saved = (const SavedState *)FMUstate;
    BEGIN(ERROR_MODES);
    if (saved == NULL || saved->magic != STATE_MAGIC || saved->size != sizeof(SavedState)) {
        FAIL("FMUstate is NULL or not a TrailerTrain state of this build (n = %d)", inst->data.n);
    }
    inst->data = saved->data;
    inst->mode = saved->mode;
    END;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    BEGIN(ERROR_MODES);
    if (FMUstate != NULL) {
        free(*FMUstate);
        *FMUstate = NULL;
    }
    END;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    BEGIN(ANY_MODE);
    (void)FMUstate;
    if (size == NULL) {
        FAIL("size is NULL");
    }
    *size = sizeof(SavedState);
    END;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size) {
    BEGIN(ANY_MODE);
    if (FMUstate == NULL || serializedState == NULL || size < sizeof(SavedState)) {
        FAIL("need a state and a buffer of %u bytes, got %u", (unsigned)sizeof(SavedState),
             (unsigned)size);
    }
    memcpy(serializedState, FMUstate, sizeof(SavedState));
    END;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    SavedState header;
    SavedState *saved;
    BEGIN(ANY_MODE);
    if (serializedState == NULL || FMUstate == NULL || size != sizeof(SavedState)) {
        FAIL("serialized state has %u bytes; this build (n = %d) expects %u", (unsigned)size,
             inst->data.n, (unsigned)sizeof(SavedState));
    }
    memcpy(&header, serializedState, sizeof(SavedState));
    if (header.magic != STATE_MAGIC || header.size != sizeof(SavedState)) {
        FAIL("not a TrailerTrain state of this build");
    }
    saved = (SavedState *)*FMUstate;
    if (saved == NULL) {
        saved = (SavedState *)malloc(sizeof(SavedState));
        if (saved == NULL) {
            FAIL("out of memory");
        }
    }
    *saved = header;
    *FMUstate = saved;
    END;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    return not_supported(c, __func__, "providesDirectionalDerivative = false");
}

/* ---------------------------------------------------------------- co-simulation */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return not_supported(c, __func__, "canInterpolateInputs = false");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return not_supported(c, __func__, "maxOutputDerivativeOrder = 0");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    const double t = currentCommunicationPoint, h = communicationStepSize;
    double tolerance;
    BEGIN(mode_step_complete);
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!(h > 0.0) || !isfinite(h)) {
        FAIL("communicationStepSize = %g: must be finite and > 0", h);
    }
    if (h / inst->data.max_substep > 1e9) {
        FAIL("communicationStepSize = %g s needs more than 1e9 substeps of max_substep = %g s", h,
             inst->data.max_substep);
    }
    /* Importers accumulate times differently (sums of floats, integer nanoseconds). */
    tolerance = 1e-9 + 1e-12 * fabs(inst->data.time);
    if (!isfinite(t) || fabs(t - inst->data.time) > tolerance) {
        FAIL("currentCommunicationPoint = %.17g differs from the FMU's time %.17g", t,
             inst->data.time);
    }
    if (inst->stop_time_defined && t + h > inst->stop_time + tolerance) {
        FAIL("the step from t = %.17g by %.17g s ends after stopTime = %.17g (set in "
             "fmi2SetupExperiment)", t, h, inst->stop_time);
    }
    inst->data.time = t;
    if (inst->log_debug && inst->logging_on) {
        log_message(inst, fmi2OK, "logDebug", "%s: t = %.9g, h = %.9g", __func__, t, h);
    }
    model_integrate(&inst->data, h, t + h);
    if (model_state_is_finite(&inst->data)) {
        model_compute_outputs(&inst->data); /* outputs of the new point, checked once here */
    }
    if (!model_state_is_finite(&inst->data) || !model_outputs_are_finite(&inst->data)) {
        FAIL("the state or outputs became non-finite in the step from t = %.9g to %.9g (inputs "
             "v_cmd = %g, w_cmd = %g)", t, t + h, inst->data.v_cmd, inst->data.w_cmd);
    }
    END;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    return not_supported(c, __func__, "fmi2DoStep never returns fmi2Pending");
}

/* FMI 2.0: a status the slave cannot provide is answered with fmi2Discard (not an error). */
static fmi2Status status_not_provided(Instance *inst, const char *function, fmi2StatusKind s) {
    log_message(inst, fmi2Discard, "logStatusWarning", "%s: status kind %d is not provided "
                "(fmi2DoStep never returns fmi2Pending)", function, (int)s);
    return fmi2Discard;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    BEGIN(ERROR_MODES);
    (void)value;
    status = status_not_provided(inst, __func__, s);
    END;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    BEGIN(ERROR_MODES);
    if (value == NULL) {
        FAIL("value is NULL");
    }
    if (s == fmi2LastSuccessfulTime) {
        *value = inst->data.time;
    } else {
        status = status_not_provided(inst, __func__, s);
    }
    END;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    BEGIN(ERROR_MODES);
    (void)value;
    status = status_not_provided(inst, __func__, s);
    END;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    BEGIN(ERROR_MODES);
    if (value == NULL) {
        FAIL("value is NULL");
    }
    if (s == fmi2Terminated) {
        *value = fmi2False; /* the model never asks the master to stop */
    } else {
        status = status_not_provided(inst, __func__, s);
    }
    END;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    BEGIN(ERROR_MODES);
    (void)value;
    status = status_not_provided(inst, __func__, s);
    END;
}
