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

#define ANY_MODE (mode_instantiated | mode_initialization | mode_step_complete | mode_terminated)
#define SETUP_MODES (mode_instantiated | mode_initialization)
#define MSG_LEN 512
#define STATE_MAGIC 0x54524e31u /* "TRN1" */

typedef struct {
    ModelData data;
    Mode mode;
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
    if (status == fmi2Warning && !inst->log_warnings) {
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

static fmi2Status fail(Instance *inst, const char *function, const char *fmt, ...) {
    char buffer[MSG_LEN];
    va_list args;
    va_start(args, fmt);
    vsnprintf(buffer, sizeof(buffer), fmt, args);
    va_end(args);
    log_message(inst, fmi2Error, "logStatusError", "%s: %s", function, buffer);
    return fmi2Error;
}

static const char *mode_name(Mode mode) {
    switch (mode) {
    case mode_instantiated: return "Instantiated";
    case mode_initialization: return "InitializationMode";
    case mode_step_complete: return "StepComplete";
    case mode_terminated: return "Terminated";
    default: return "Error";
    }
}

/* Guard: the call is allowed in `allowed` modes and c is not NULL. */
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

static bool setup_mode(const Instance *inst) {
    return inst->mode == mode_instantiated || inst->mode == mode_initialization;
}

/* Makes the outputs current. Before initialization ends they follow the (possibly changed) start
   parameters, which must then be valid; after an error with a non-finite state there are none. */
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
    Instance *inst = (Instance *)c;
    size_t k;
    if (!allowed(inst, "fmi2SetDebugLogging", ANY_MODE)) {
        return fmi2Error;
    }
    inst->logging_on = loggingOn;
    if (nCategories == 0) {
        /* loggingOn applies to all categories; errors and warnings are always reported */
        inst->log_debug = loggingOn;
        inst->log_errors = fmi2True;
        inst->log_warnings = fmi2True;
        return fmi2OK;
    }
    if (categories == NULL) {
        return fail(inst, "fmi2SetDebugLogging", "categories = NULL with nCategories = %u",
                    (unsigned)nCategories);
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
            return fail(inst, "fmi2SetDebugLogging",
                        "unknown log category '%s'; allowed: %s, %s, %s",
                        name ? name : "(null)", log_categories[0], log_categories[1],
                        log_categories[2]);
        }
    }
    return fmi2OK;
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
                          "fmi2Instantiate: fmuType = %d: TrailerTrain supports only "
                          "fmi2CoSimulation (%d)", (int)fmuType, (int)fmi2CoSimulation);
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, MODEL_GUID) != 0) {
        functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                          "fmi2Instantiate: GUID '%s' does not match this binary's '%s' "
                          "(the modelDescription.xml belongs to another build)",
                          fmuGUID ? fmuGUID : "(null)", MODEL_GUID);
        return NULL;
    }
    inst = (Instance *)calloc(1, sizeof(Instance));
    if (inst == NULL) {
        functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                          "fmi2Instantiate: out of memory");
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
    Instance *inst = (Instance *)c;
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (!allowed(inst, "fmi2SetupExperiment", mode_instantiated)) {
        return fmi2Error;
    }
    if (!isfinite(startTime)) {
        return fail(inst, "fmi2SetupExperiment", "startTime = %g: must be finite", startTime);
    }
    inst->data.time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2EnterInitializationMode", mode_instantiated)) {
        return fmi2Error;
    }
    inst->mode = mode_initialization;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    char msg[MSG_LEN];
    if (!allowed(inst, "fmi2ExitInitializationMode", mode_initialization)) {
        return fmi2Error;
    }
    /* Parameters may have been set after fmi2EnterInitializationMode (FMIL-based importers):
       everything is derived from them here. */
    if (!model_check_parameters(&inst->data, msg, sizeof(msg))) {
        inst->mode = mode_error;
        return fail(inst, "fmi2ExitInitializationMode", "%s", msg);
    }
    model_state_from_start(&inst->data);
    model_compute_outputs(&inst->data);
    if (!model_outputs_are_finite(&inst->data)) {
        inst->mode = mode_error;
        return fail(inst, "fmi2ExitInitializationMode", "the start values give non-finite "
                    "outputs (v_start = %g, w_start = %g, v_cmd = %g, w_cmd = %g)",
                    inst->data.v_start, inst->data.w_start, inst->data.v_cmd, inst->data.w_cmd);
    }
    inst->mode = mode_step_complete;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2Terminate", mode_step_complete | mode_error)) {
        return fmi2Error;
    }
    inst->mode = mode_terminated;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2Reset", ANY_MODE | mode_error)) {
        return fmi2Error;
    }
    model_set_defaults(&inst->data);
    inst->mode = mode_instantiated;
    return fmi2OK;
}

/* ---------------------------------------------------------------- get */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    char msg[MSG_LEN];
    size_t k;
    if (!allowed(inst, "fmi2GetReal", ANY_MODE | mode_error)) {
        return fmi2Error;
    }
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        return fail(inst, "fmi2GetReal", "vr or value is NULL");
    }
    for (k = 0; k < nvr; k++) {
        if (model_needs_outputs(vr[k]) && ensure_outputs(inst, "fmi2GetReal") != fmi2OK) {
            return fmi2Error;
        }
        if (!model_get_real(&inst->data, vr[k], &value[k], msg, sizeof(msg))) {
            return fail(inst, "fmi2GetReal", "%s", msg);
        }
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    Instance *inst = (Instance *)c;
    char msg[MSG_LEN];
    size_t k;
    if (!allowed(inst, "fmi2GetInteger", ANY_MODE | mode_error)) {
        return fmi2Error;
    }
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        return fail(inst, "fmi2GetInteger", "vr or value is NULL");
    }
    for (k = 0; k < nvr; k++) {
        int v;
        if (!model_get_integer(&inst->data, vr[k], &v, msg, sizeof(msg))) {
            return fail(inst, "fmi2GetInteger", "%s", msg);
        }
        value[k] = v;
    }
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    Instance *inst = (Instance *)c;
    char msg[MSG_LEN];
    size_t k;
    if (!allowed(inst, "fmi2GetBoolean", ANY_MODE | mode_error)) {
        return fmi2Error;
    }
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        return fail(inst, "fmi2GetBoolean", "vr or value is NULL");
    }
    if (nvr > 0 && ensure_outputs(inst, "fmi2GetBoolean") != fmi2OK) {
        return fmi2Error;
    }
    for (k = 0; k < nvr; k++) {
        bool v;
        if (!model_get_boolean(&inst->data, vr[k], &v, msg, sizeof(msg))) {
            return fail(inst, "fmi2GetBoolean", "%s", msg);
        }
        value[k] = v ? fmi2True : fmi2False;
    }
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    Instance *inst = (Instance *)c;
    (void)value;
    if (!allowed(inst, "fmi2GetString", ANY_MODE | mode_error)) {
        return fmi2Error;
    }
    if (nvr > 0) {
        return fail(inst, "fmi2GetString", "value reference %u: TrailerTrain has no String "
                    "variables", (unsigned)(vr ? vr[0] : 0));
    }
    return fmi2OK;
}

/* ---------------------------------------------------------------- set */

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    char msg[MSG_LEN];
    size_t k;
    if (!allowed(inst, "fmi2SetReal", SETUP_MODES | mode_step_complete)) {
        return fmi2Error;
    }
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        return fail(inst, "fmi2SetReal", "vr or value is NULL");
    }
    for (k = 0; k < nvr; k++) {
        if (!model_set_real(&inst->data, vr[k], value[k], setup_mode(inst), msg, sizeof(msg))) {
            return fail(inst, "fmi2SetReal", "%s", msg);
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    Instance *inst = (Instance *)c;
    char msg[MSG_LEN];
    size_t k;
    if (!allowed(inst, "fmi2SetInteger", SETUP_MODES)) {
        return fmi2Error;
    }
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        return fail(inst, "fmi2SetInteger", "vr or value is NULL");
    }
    for (k = 0; k < nvr; k++) {
        if (!model_set_integer(&inst->data, vr[k], value[k], setup_mode(inst), msg,
                               sizeof(msg))) {
            return fail(inst, "fmi2SetInteger", "%s", msg);
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    Instance *inst = (Instance *)c;
    char msg[MSG_LEN];
    size_t k;
    if (!allowed(inst, "fmi2SetBoolean", ANY_MODE)) {
        return fmi2Error;
    }
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        return fail(inst, "fmi2SetBoolean", "vr or value is NULL");
    }
    for (k = 0; k < nvr; k++) {
        if (!model_set_boolean(&inst->data, vr[k], value[k] != fmi2False, setup_mode(inst), msg,
                               sizeof(msg))) {
            return fail(inst, "fmi2SetBoolean", "%s", msg);
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    Instance *inst = (Instance *)c;
    (void)value;
    if (!allowed(inst, "fmi2SetString", ANY_MODE)) {
        return fmi2Error;
    }
    if (nvr > 0) {
        return fail(inst, "fmi2SetString", "value reference %u: TrailerTrain has no String "
                    "variables", (unsigned)(vr ? vr[0] : 0));
    }
    return fmi2OK;
}

/* ---------------------------------------------------------------- FMU state */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Instance *inst = (Instance *)c;
    SavedState *saved;
    if (!allowed(inst, "fmi2GetFMUstate", ANY_MODE)) {
        return fmi2Error;
    }
    if (FMUstate == NULL) {
        return fail(inst, "fmi2GetFMUstate", "FMUstate is NULL");
    }
    saved = (SavedState *)*FMUstate;
    if (saved == NULL) {
        saved = (SavedState *)calloc(1, sizeof(SavedState));
        if (saved == NULL) {
            return fail(inst, "fmi2GetFMUstate", "out of memory");
        }
    }
    saved->magic = STATE_MAGIC;
    saved->size = (unsigned int)sizeof(SavedState);
    saved->mode = inst->mode;
    saved->data = inst->data;
    *FMUstate = saved;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    Instance *inst = (Instance *)c;
    const SavedState *saved = (const SavedState *)FMUstate;
    if (!allowed(inst, "fmi2SetFMUstate", ANY_MODE)) {
        return fmi2Error;
    }
    if (saved == NULL || saved->magic != STATE_MAGIC || saved->size != sizeof(SavedState)) {
        return fail(inst, "fmi2SetFMUstate", "FMUstate is NULL or not a TrailerTrain state of "
                    "this build (n = %d)", N_TRAILERS);
    }
    inst->data = saved->data;
    inst->mode = saved->mode;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2FreeFMUstate", ANY_MODE | mode_error)) {
        return fmi2Error;
    }
    if (FMUstate != NULL) {
        free(*FMUstate);
        *FMUstate = NULL;
    }
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    Instance *inst = (Instance *)c;
    (void)FMUstate;
    if (!allowed(inst, "fmi2SerializedFMUstateSize", ANY_MODE)) {
        return fmi2Error;
    }
    if (size == NULL) {
        return fail(inst, "fmi2SerializedFMUstateSize", "size is NULL");
    }
    *size = sizeof(SavedState);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2SerializeFMUstate", ANY_MODE)) {
        return fmi2Error;
    }
    if (FMUstate == NULL || serializedState == NULL || size < sizeof(SavedState)) {
        return fail(inst, "fmi2SerializeFMUstate", "need a state and a buffer of %u bytes, got "
                    "%u", (unsigned)sizeof(SavedState), (unsigned)size);
    }
    memcpy(serializedState, FMUstate, sizeof(SavedState));
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    Instance *inst = (Instance *)c;
    SavedState header;
    SavedState *saved;
    if (!allowed(inst, "fmi2DeSerializeFMUstate", ANY_MODE)) {
        return fmi2Error;
    }
    if (serializedState == NULL || FMUstate == NULL || size != sizeof(SavedState)) {
        return fail(inst, "fmi2DeSerializeFMUstate", "serialized state has %u bytes; this build "
                    "(n = %d) expects %u", (unsigned)size, N_TRAILERS,
                    (unsigned)sizeof(SavedState));
    }
    memcpy(&header, serializedState, sizeof(SavedState));
    if (header.magic != STATE_MAGIC || header.size != sizeof(SavedState)) {
        return fail(inst, "fmi2DeSerializeFMUstate", "not a TrailerTrain state of this build");
    }
    saved = (SavedState *)*FMUstate;
    if (saved == NULL) {
        saved = (SavedState *)malloc(sizeof(SavedState));
        if (saved == NULL) {
            return fail(inst, "fmi2DeSerializeFMUstate", "out of memory");
        }
    }
    *saved = header;
    *FMUstate = saved;
    return fmi2OK;
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
    return fail((Instance *)c, "fmi2GetDirectionalDerivative",
                "not supported (providesDirectionalDerivative = false)");
}

/* ---------------------------------------------------------------- co-simulation */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return fail((Instance *)c, "fmi2SetRealInputDerivatives",
                "not supported (canInterpolateInputs = false)");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return fail((Instance *)c, "fmi2GetRealOutputDerivatives",
                "not supported (maxOutputDerivativeOrder = 0)");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Instance *inst = (Instance *)c;
    const double t = currentCommunicationPoint, h = communicationStepSize;
    double tolerance;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!allowed(inst, "fmi2DoStep", mode_step_complete)) {
        return fmi2Error;
    }
    if (!(h > 0.0) || !isfinite(h)) {
        return fail(inst, "fmi2DoStep", "communicationStepSize = %g: must be finite and > 0", h);
    }
    if (h / inst->data.max_substep > 1e9) {
        return fail(inst, "fmi2DoStep", "communicationStepSize = %g s needs more than 1e9 "
                    "substeps of max_substep = %g s", h, inst->data.max_substep);
    }
    /* Importers accumulate times differently (sums of floats, integer nanoseconds). */
    tolerance = 1e-9 + 1e-12 * fabs(inst->data.time);
    if (!isfinite(t) || fabs(t - inst->data.time) > tolerance) {
        return fail(inst, "fmi2DoStep", "currentCommunicationPoint = %.17g differs from the "
                    "FMU's time %.17g", t, inst->data.time);
    }
    inst->data.time = t;
    if (inst->log_debug && inst->logging_on) {
        log_message(inst, fmi2OK, "logDebug", "fmi2DoStep: t = %.9g, h = %.9g", t, h);
    }
    model_integrate(&inst->data, h, t + h);
    if (model_state_is_finite(&inst->data)) {
        model_compute_outputs(&inst->data); /* outputs of the new point, checked once here */
    }
    if (!model_state_is_finite(&inst->data) || !model_outputs_are_finite(&inst->data)) {
        inst->mode = mode_error;
        return fail(inst, "fmi2DoStep", "the state or outputs became non-finite in the step from t = %.9g "
                    "to %.9g (inputs v_cmd = %g, w_cmd = %g)", t, t + h, inst->data.v_cmd,
                    inst->data.w_cmd);
    }
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    return fail((Instance *)c, "fmi2CancelStep", "not supported: fmi2DoStep never returns "
                "fmi2Pending");
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s;
    (void)value;
    return fail((Instance *)c, "fmi2GetStatus", "not supported: fmi2DoStep never returns "
                "fmi2Pending");
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2GetRealStatus", ANY_MODE | mode_error)) {
        return fmi2Error;
    }
    if (s == fmi2LastSuccessfulTime && value != NULL) {
        *value = inst->data.time;
        return fmi2OK;
    }
    return fail(inst, "fmi2GetRealStatus", "status kind %d is not supported", (int)s);
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s;
    (void)value;
    return fail((Instance *)c, "fmi2GetIntegerStatus", "not supported");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    Instance *inst = (Instance *)c;
    if (!allowed(inst, "fmi2GetBooleanStatus", ANY_MODE | mode_error)) {
        return fmi2Error;
    }
    if (s == fmi2Terminated && value != NULL) {
        *value = fmi2False; /* the model never asks the master to stop */
        return fmi2OK;
    }
    return fail(inst, "fmi2GetBooleanStatus", "status kind %d is not supported", (int)s);
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)s;
    (void)value;
    return fail((Instance *)c, "fmi2GetStringStatus", "not supported");
}
