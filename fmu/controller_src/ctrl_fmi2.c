/*
 * FMI 2.0 Co-Simulation interface of the BackwardController FMU, written from the FMI 2.0.x
 * specification, in the manner of the plant's glue (fmu/src/fmi2.c): every function checks the
 * instance's mode first; a failure logs "function: what is wrong" and moves the instance to the
 * error state, where only getters, reset and free are allowed. No mutable static state.
 *
 * fmi2Instantiate reads the mission table from the resource folder; parameters may be set
 * before or after fmi2EnterInitializationMode (FMIL-based importers set them after) and are
 * checked in fmi2ExitInitializationMode. Inputs must be finite (as the plant's).
 */
#include <math.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "ctrl_model.h"

typedef enum {
    mode_instantiated = 1,
    mode_initialization = 2,
    mode_step = 4,
    mode_terminated = 8,
    mode_error = 16
} Mode;

#define SETUP_MODES (mode_instantiated | mode_initialization)
#define ANY_MODE (mode_instantiated | mode_initialization | mode_step | mode_terminated)
#define ERROR_MODES (ANY_MODE | mode_error)
#define PATH_LEN 4096

typedef struct {
    CtrlModel model;
    CtrlTable table;
    Mode mode;
    char *name;
    fmi2CallbackFunctions callbacks;
    bool logging_on, log_debug, log_errors, log_warnings;
    bool stop_time_defined;
    double stop_time;
    /* communication points: start + k h while the master's points stay on the grid of its first
       step h (as a master computes them, never by summing floats; a phase of the reference that
       ends on a point is then sampled alike), else the last point plus its step */
    double start_time, step_size;
    long steps;
} Ctrl;

/* ---------------------------------------------------------------- logging and modes */

static void ctrl_log(const Ctrl *c, fmi2Status status, const char *category, const char *fmt,
                     ...) {
    char buffer[CTRL_MSG_LEN];
    va_list args;
    if (status == fmi2OK && !(c->logging_on && c->log_debug)) {
        return;
    }
    if ((status == fmi2Warning || status == fmi2Discard) && !c->log_warnings) {
        return;
    }
    if (status >= fmi2Error && !c->log_errors) {
        return;
    }
    va_start(args, fmt);
    vsnprintf(buffer, sizeof(buffer), fmt, args);
    va_end(args);
    /* the logger reads '#' as a value-reference escape: the text goes in as an argument */
    c->callbacks.logger(c->callbacks.componentEnvironment, c->name, status, category, "%s",
                        buffer);
}

static fmi2Status ctrl_fail(Ctrl *c, const char *function, const char *fmt, ...) {
    char buffer[CTRL_MSG_LEN];
    va_list args;
    va_start(args, fmt);
    vsnprintf(buffer, sizeof(buffer), fmt, args);
    va_end(args);
    ctrl_log(c, fmi2Error, "logStatusError", "%s: %s", function, buffer);
    c->mode = mode_error;
    return fmi2Error;
}

static const char *mode_name(Mode mode) {
    switch (mode) {
    case mode_instantiated: return "Instantiated";
    case mode_initialization: return "InitializationMode";
    case mode_step: return "StepComplete";
    case mode_terminated: return "Terminated";
    case mode_error: break;
    }
    return "Error (after an fmi2Error; only fmi2GetXXX, fmi2Reset and fmi2FreeInstance are "
           "allowed)";
}

static bool allowed(Ctrl *c, const char *function, int modes) {
    if (c == NULL) {
        return false;
    }
    if (!(c->mode & modes)) {
        ctrl_fail(c, function, "not allowed in mode %s", mode_name(c->mode));
        return false;
    }
    return true;
}

#define BEGIN(modes)                                                                            \
    Ctrl *const inst = (Ctrl *)c;                                                               \
    fmi2Status status = fmi2OK;                                                                 \
    if (!allowed(inst, __func__, (modes))) {                                                    \
        return fmi2Error;                                                                       \
    }
#define FAIL(...) return ctrl_fail(inst, __func__, __VA_ARGS__)
#define END return status

static fmi2Status not_supported(fmi2Component c, const char *function, const char *why) {
    if (c == NULL) {
        return fmi2Error;
    }
    return ctrl_fail((Ctrl *)c, function, "not supported (%s)", why);
}

/* ---------------------------------------------------------------- common functions */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    size_t k;
    BEGIN(ERROR_MODES);
    inst->logging_on = loggingOn != fmi2False;
    if (nCategories == 0) {
        inst->log_debug = inst->logging_on;
        inst->log_errors = true;
        inst->log_warnings = true;
        END;
    }
    if (categories == NULL) {
        FAIL("categories = NULL with nCategories = %u", (unsigned)nCategories);
    }
    for (k = 0; k < nCategories; k++) {
        const char *name = categories[k];
        if (name != NULL && strcmp(name, "logDebug") == 0) {
            inst->log_debug = inst->logging_on;
        } else if (name != NULL && strcmp(name, "logStatusError") == 0) {
            inst->log_errors = inst->logging_on;
        } else if (name != NULL && strcmp(name, "logStatusWarning") == 0) {
            inst->log_warnings = inst->logging_on;
        } else {
            FAIL("unknown log category '%s'; allowed: logStatusError, logStatusWarning, "
                 "logDebug", name ? name : "(null)");
        }
    }
    END;
}

static void refuse(const fmi2CallbackFunctions *functions, const char *name,
                   const char *message) {
    functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                      "fmi2Instantiate: %s", message);
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    char path[PATH_LEN], msg[CTRL_MSG_LEN];
    const char *name = instanceName ? instanceName : "BackwardController";
    Ctrl *inst;
    (void)visible;
    if (functions == NULL || functions->logger == NULL) {
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        refuse(functions, name, "BackwardController supports only fmi2CoSimulation");
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, CTRL_GUID) != 0) {
        snprintf(msg, sizeof(msg), "GUID '%s' does not match this binary's '%s' (the "
                 "modelDescription.xml belongs to another build)", fmuGUID ? fmuGUID : "(null)",
                 CTRL_GUID);
        refuse(functions, name, msg);
        return NULL;
    }
    if (!ctrl_resource_path(fmuResourceLocation, CTRL_TABLE_FILE, path, sizeof(path), msg,
                            sizeof(msg))) {
        refuse(functions, name, msg);
        return NULL;
    }
    inst = (Ctrl *)calloc(1, sizeof(Ctrl));
    if (inst == NULL || (inst->name = (char *)malloc(strlen(name) + 1)) == NULL) {
        free(inst);
        refuse(functions, name, "out of memory");
        return NULL;
    }
    strcpy(inst->name, name);
    if (!ctrl_table_load(path, &inst->table, msg, sizeof(msg))
        || !ctrl_model_init(&inst->model, &inst->table, msg, sizeof(msg))) {
        refuse(functions, name, msg);
        ctrl_table_free(&inst->table);
        free(inst->name);
        free(inst);
        return NULL;
    }
    memcpy(&inst->callbacks, functions, sizeof(fmi2CallbackFunctions));
    inst->logging_on = loggingOn != fmi2False;
    inst->log_errors = true;
    inst->log_warnings = true;
    inst->mode = mode_instantiated;
    return inst;
}

void fmi2FreeInstance(fmi2Component c) {
    Ctrl *inst = (Ctrl *)c;
    if (inst == NULL) {
        return;
    }
    ctrl_model_free(&inst->model);
    ctrl_table_free(&inst->table);
    free(inst->name);
    free(inst);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    BEGIN(mode_instantiated);
    (void)toleranceDefined;
    (void)tolerance;
    if (!isfinite(startTime)) {
        FAIL("startTime = %g: must be finite", startTime);
    }
    if (stopTimeDefined && !(stopTime >= startTime)) {
        FAIL("stopTime = %g: must be >= startTime = %g", stopTime, startTime);
    }
    inst->model.time = startTime;
    inst->start_time = startTime;
    inst->steps = 0;
    inst->stop_time_defined = stopTimeDefined != fmi2False;
    inst->stop_time = stopTime;
    ctrl_model_start(&inst->model);
    END;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    BEGIN(mode_instantiated);
    inst->mode = mode_initialization;
    END;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    char msg[CTRL_MSG_LEN];
    BEGIN(mode_initialization);
    if (!ctrl_model_check_parameters(&inst->model, msg, sizeof(msg))) {
        FAIL("%s", msg);
    }
    ctrl_model_start(&inst->model);
    inst->mode = mode_step;
    END;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    BEGIN(mode_step);
    inst->mode = mode_terminated;
    END;
}

fmi2Status fmi2Reset(fmi2Component c) {
    BEGIN(ERROR_MODES);
    ctrl_model_set_defaults(&inst->model);
    inst->start_time = 0.0;
    inst->steps = 0;
    inst->stop_time_defined = false;
    inst->mode = mode_instantiated;
    END;
}

/* ---------------------------------------------------------------- get and set */

static const CtrlVarInfo *lookup(Ctrl *inst, const char *function, fmi2ValueReference vr,
                                 CtrlType type) {
    static const char *const type_names[] = {"Real", "Integer", "Boolean"};
    const CtrlVarInfo *v = (vr < CTRL_VR_END) ? &ctrl_vars[vr] : NULL;
    if (v == NULL || v->name == NULL) {
        ctrl_fail(inst, function, "value reference %u: no such variable", (unsigned)vr);
        return NULL;
    }
    if (v->type != type) {
        ctrl_fail(inst, function, "%s (value reference %u) is a %s variable, not %s", v->name,
                  (unsigned)vr, type_names[v->type], type_names[type]);
        return NULL;
    }
    return v;
}

/* The outputs made current for a get of an output; before initialization ends the parameters
 * must already be valid. */
static fmi2Status ensure_outputs(Ctrl *inst, const char *function) {
    char msg[CTRL_MSG_LEN];
    if (inst->mode == mode_error) {
        return fmi2OK; /* diagnostics: the last values */
    }
    if ((inst->mode & SETUP_MODES)
        && !ctrl_model_check_parameters(&inst->model, msg, sizeof(msg))) {
        return ctrl_fail(inst, function, "outputs cannot be computed: %s", msg);
    }
    if (!ctrl_model_evaluate(&inst->model, msg, sizeof(msg))) {
        return ctrl_fail(inst, function, "%s", msg);
    }
    return fmi2OK;
}

static fmi2Status get_values(Ctrl *inst, const char *function, const fmi2ValueReference vr[],
                             size_t nvr, CtrlType type, void *values) {
    size_t k;
    bool current = false;
    if (nvr > 0 && (vr == NULL || values == NULL)) {
        return ctrl_fail(inst, function, "vr or value is NULL");
    }
    for (k = 0; k < nvr; k++) {
        const CtrlVarInfo *v = lookup(inst, function, vr[k], type);
        if (v == NULL) {
            return fmi2Error;
        }
        if (v->causality == ctrl_output && !current) {
            if (ensure_outputs(inst, function) != fmi2OK) {
                return fmi2Error;
            }
            current = true;
        }
        if (type == ctrl_real) {
            ((fmi2Real *)values)[k] = inst->model.r[v->offset];
        } else if (type == ctrl_integer) {
            ((fmi2Integer *)values)[k] = inst->model.i[v->offset];
        } else {
            ((fmi2Boolean *)values)[k] = inst->model.b[v->offset] ? fmi2True : fmi2False;
        }
    }
    return fmi2OK;
}

/* Parameters before initialization ends, inputs in any mode but Terminated; every value of a
 * Real must be finite. */
static fmi2Status check_set(Ctrl *inst, const char *function, const CtrlVarInfo *v,
                            double value) {
    if (v->causality == ctrl_output || v->causality == ctrl_calculated_parameter) {
        return ctrl_fail(inst, function, "%s is an %s: it cannot be set", v->name,
                         v->causality == ctrl_output ? "output" : "calculated parameter");
    }
    if (v->causality == ctrl_parameter && !(inst->mode & SETUP_MODES)) {
        return ctrl_fail(inst, function, "parameter %s cannot be set in mode %s (fixed after "
                         "initialization)", v->name, mode_name(inst->mode));
    }
    if (v->causality == ctrl_input && inst->mode == mode_terminated) {
        return ctrl_fail(inst, function, "input %s cannot be set after fmi2Terminate", v->name);
    }
    if (!isfinite(value)) {
        return ctrl_fail(inst, function, "%s %s = %g: must be finite",
                         v->causality == ctrl_input ? "input" : "parameter", v->name, value);
    }
    return fmi2OK;
}

static void changed(Ctrl *inst, const CtrlVarInfo *v) {
    if (v->causality == ctrl_parameter) {
        ctrl_model_start(&inst->model); /* the start memory follows v_start, w_start, dt_start */
    } else {
        inst->model.evaluated = false;
    }
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    BEGIN(ERROR_MODES);
    status = get_values(inst, __func__, vr, nvr, ctrl_real, value);
    END;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    BEGIN(ERROR_MODES);
    status = get_values(inst, __func__, vr, nvr, ctrl_integer, value);
    END;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    BEGIN(ERROR_MODES);
    status = get_values(inst, __func__, vr, nvr, ctrl_boolean, value);
    END;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    BEGIN(ERROR_MODES);
    (void)value;
    if (nvr > 0) {
        FAIL("value reference %u: BackwardController has no String variables",
             (unsigned)(vr ? vr[0] : 0));
    }
    END;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    size_t k;
    BEGIN(ANY_MODE);
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        FAIL("vr or value is NULL");
    }
    for (k = 0; k < nvr; k++) {
        const CtrlVarInfo *v = lookup(inst, __func__, vr[k], ctrl_real);
        if (v == NULL || check_set(inst, __func__, v, value[k]) != fmi2OK) {
            return fmi2Error;
        }
        inst->model.r[v->offset] = value[k];
        changed(inst, v);
    }
    END;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    BEGIN(ANY_MODE);
    (void)value;
    if (nvr > 0) {
        const CtrlVarInfo *v = lookup(inst, __func__, vr ? vr[0] : 0, ctrl_integer);
        if (v != NULL) {
            FAIL("%s is an output: it cannot be set", v->name);
        }
        return fmi2Error;
    }
    END;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    size_t k;
    BEGIN(ANY_MODE);
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        FAIL("vr or value is NULL");
    }
    for (k = 0; k < nvr; k++) {
        const CtrlVarInfo *v = lookup(inst, __func__, vr[k], ctrl_boolean);
        if (v == NULL || check_set(inst, __func__, v, 0.0) != fmi2OK) {
            return fmi2Error;
        }
        inst->model.b[v->offset] = value[k] != fmi2False;
        changed(inst, v);
    }
    END;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    BEGIN(ANY_MODE);
    (void)value;
    if (nvr > 0) {
        FAIL("value reference %u: BackwardController has no String variables",
             (unsigned)(vr ? vr[0] : 0));
    }
    END;
}

/* ---------------------------------------------------------------- not provided */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    (void)FMUstate;
    return not_supported(c, __func__, "canGetAndSetFMUstate = false");
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    (void)FMUstate;
    return not_supported(c, __func__, "canGetAndSetFMUstate = false");
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    (void)FMUstate;
    return not_supported(c, __func__, "canGetAndSetFMUstate = false");
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    (void)FMUstate;
    (void)size;
    return not_supported(c, __func__, "canSerializeFMUstate = false");
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate,
                                 fmi2Byte serializedState[], size_t size) {
    (void)FMUstate;
    (void)serializedState;
    (void)size;
    return not_supported(c, __func__, "canSerializeFMUstate = false");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate) {
    (void)serializedState;
    (void)size;
    (void)FMUstate;
    return not_supported(c, __func__, "canSerializeFMUstate = false");
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

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
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

/* ---------------------------------------------------------------- co-simulation */

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    char msg[CTRL_MSG_LEN];
    const double t = currentCommunicationPoint, h = communicationStepSize;
    double tolerance, t_next;
    BEGIN(mode_step);
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!(h > 0.0) || !isfinite(h)) {
        FAIL("communicationStepSize = %g: must be finite and > 0", h);
    }
    tolerance = 1e-9 + 1e-12 * fabs(inst->model.time);
    if (!isfinite(t) || fabs(t - inst->model.time) > tolerance) {
        FAIL("currentCommunicationPoint = %.17g differs from the FMU's time %.17g", t,
             inst->model.time);
    }
    if (inst->stop_time_defined && t + h > inst->stop_time + tolerance) {
        FAIL("the step from t = %.17g by %.17g s ends after stopTime = %.17g", t, h,
             inst->stop_time);
    }
    if (inst->steps == 0) {
        inst->step_size = h;
    }
    t_next = inst->start_time + (double)(inst->steps + 1) * inst->step_size;
    if (inst->steps >= 0 && fabs(t + h - t_next) <= tolerance) {
        inst->steps++; /* on the grid of the first step (masters jitter h by an ulp) */
    } else {
        inst->steps = -1; /* variable steps from here on */
        t_next = t + h;
    }
    if (!ctrl_model_step(&inst->model, t_next, msg, sizeof(msg))) {
        FAIL("%s", msg);
    }
    ctrl_log(inst, fmi2OK, "logDebug", "%s: t = %.9g, h = %.9g", __func__, t, h);
    END;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    return not_supported(c, __func__, "fmi2DoStep never returns fmi2Pending");
}

static fmi2Status status_not_provided(Ctrl *inst, const char *function, fmi2StatusKind s) {
    ctrl_log(inst, fmi2Discard, "logStatusWarning", "%s: status kind %d is not provided",
             function, (int)s);
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
        *value = inst->model.time;
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
        *value = fmi2False; /* done is an output: the master decides when to stop */
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
