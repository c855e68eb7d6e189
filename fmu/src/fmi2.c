/*
 * FMI 2.0 Co-Simulation interface, written from the FMI 2.0.x specification, of both FMUs of
 * pushtrain: the plant TrailerTrain and the BackwardController (MODEL_IDENTIFIER of the build).
 *
 * A thin translation onto instance.c (names, types, statuses); the rules both standards share
 * live there, the model behind fmu_model.h. Only the fmi2* functions are exported (the headers
 * come from the importing tool, e.g. fmpy); everything else is static or hidden. No mutable
 * static state.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "instance.h"

#if FMI_VERSION != 2
#error "fmi2.c is the glue of the FMI 2.0 build (FMI_VERSION 2 in build_config.h)"
#endif

typedef struct {
    Instance core; /* first member: an fmi2Component points to both */
    fmi2CallbackFunctions callbacks;
} Fmi2Instance;

/* FMI 2.0: after a function returned fmi2Error the instance is in the error state; then only
   fmi2GetXXX (for diagnostics), fmi2SetFMUstate (restart from a saved state), fmi2FreeFMUstate,
   fmi2Reset and fmi2FreeInstance are allowed (and fmi2SetDebugLogging). */

/*
 * Every fmi2 function that takes an instance starts with BEGIN(modes): the mode guard of
 * instance.c, naming the function by __func__. FAIL(...) logs "function: message", moves the
 * instance to the error state and returns fmi2Error; END returns the call's status.
 */
#define BEGIN(modes)                                                                            \
    Instance *const inst = (Instance *)c;                                                       \
    fmi2Status status = fmi2OK;                                                                 \
    if (!instance_allowed(inst, __func__, (modes))) {                                           \
        return fmi2Error;                                                                       \
    }
#define FAIL(...) return (fmi2Status)instance_fail(inst, __func__, __VA_ARGS__)
#define END return status

static void log_to_importer(const Instance *core, Status status, const char *category,
                            const char *message) {
    const Fmi2Instance *inst = (const Fmi2Instance *)core;
    /* The logger interprets '#' as a value-reference escape: the text goes in as an argument. */
    inst->callbacks.logger(inst->callbacks.componentEnvironment, core->instance_name,
                           (fmi2Status)status, category, "%s", message);
}

static fmi2Status not_supported(fmi2Component c, const char *function, const char *why) {
    return (fmi2Status)instance_not_supported((Instance *)c, function, why);
}

/* ---------------------------------------------------------------- common functions */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    BEGIN(ERROR_MODES);
    status = (fmi2Status)instance_set_debug_logging(inst, __func__, loggingOn != fmi2False,
                                                    nCategories, categories);
    END;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    char msg[MSG_LEN];
    Fmi2Instance *inst;
    const char *name = instanceName ? instanceName : MODEL_IDENTIFIER;
    (void)visible;
    if (functions == NULL || functions->logger == NULL) {
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                          "%s: fmuType = %d: " MODEL_IDENTIFIER " supports only "
                          "fmi2CoSimulation (%d)", __func__, (int)fmuType,
                          (int)fmi2CoSimulation);
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, MODEL_GUID) != 0) {
        functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                          "%s: GUID '%s' does not match this binary's '%s' (the "
                          "modelDescription.xml belongs to another build)", __func__,
                          fmuGUID ? fmuGUID : "(null)", MODEL_GUID);
        return NULL;
    }
    inst = (Fmi2Instance *)instance_new(sizeof(Fmi2Instance), name, fmuResourceLocation,
                                        log_to_importer, loggingOn != fmi2False, msg,
                                        sizeof(msg));
    if (inst == NULL) {
        functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                          "%s: %s", __func__, msg);
        return NULL;
    }
    memcpy(&inst->callbacks, functions, sizeof(fmi2CallbackFunctions));
    return inst;
}

void fmi2FreeInstance(fmi2Component c) {
    instance_free((Instance *)c);
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
    model_set_start_time(&inst->data, startTime);
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
    BEGIN(mode_initialization);
    status = (fmi2Status)instance_exit_initialization(inst, __func__);
    END;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    BEGIN(mode_step);
    inst->mode = mode_terminated;
    END;
}

fmi2Status fmi2Reset(fmi2Component c) {
    BEGIN(ERROR_MODES);
    instance_reset(inst);
    END;
}

/* ---------------------------------------------------------------- get */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    BEGIN(ERROR_MODES);
    status = (fmi2Status)instance_get_real(inst, __func__, vr, nvr, value, nvr);
    END;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    BEGIN(ERROR_MODES);
    status = (fmi2Status)instance_get_integer(inst, __func__, vr, nvr, value, nvr);
    END;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    enum { chunk = 64 };
    bool buffer[chunk];
    size_t done, k;
    BEGIN(ERROR_MODES);
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        FAIL("vr or value is NULL");
    }
    /* fmi2Boolean is an int: read through a bool buffer, one value per scalar variable, a chunk
       at a time (the outputs are made current at most once per chunk: O(values) in all) */
    for (done = 0; done < nvr; done += chunk) {
        const size_t count = (nvr - done < chunk) ? nvr - done : chunk;
        if (instance_get_boolean(inst, __func__, &vr[done], count, buffer, count) != status_ok) {
            return fmi2Error;
        }
        for (k = 0; k < count; k++) {
            value[done + k] = buffer[k] ? fmi2True : fmi2False;
        }
    }
    END;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    BEGIN(ERROR_MODES);
    (void)value;
    if (nvr > 0) {
        FAIL("value reference %u: " MODEL_IDENTIFIER " has no String variables",
             (unsigned)(vr ? vr[0] : 0));
    }
    END;
}

/* ---------------------------------------------------------------- set */

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    BEGIN(SETUP_MODES | mode_step);
    status = (fmi2Status)instance_set_real(inst, __func__, vr, nvr, value, nvr);
    END;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    BEGIN(SETUP_MODES);
    status = (fmi2Status)instance_set_integer(inst, __func__, vr, nvr, value, nvr);
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
        const bool v = value[k] != fmi2False;
        if (instance_set_boolean(inst, __func__, &vr[k], 1, &v, 1) != status_ok) {
            return fmi2Error;
        }
    }
    END;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    BEGIN(ANY_MODE);
    (void)value;
    if (nvr > 0) {
        FAIL("value reference %u: " MODEL_IDENTIFIER " has no String variables",
             (unsigned)(vr ? vr[0] : 0));
    }
    END;
}

/* ---------------------------------------------------------------- FMU state */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    BEGIN(ANY_MODE);
    status = (fmi2Status)instance_get_state(inst, __func__, FMUstate);
    END;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    BEGIN(ERROR_MODES);
    status = (fmi2Status)instance_set_state(inst, __func__, FMUstate);
    END;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    BEGIN(ERROR_MODES);
    status = (fmi2Status)instance_free_state(inst, __func__, FMUstate);
    END;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    BEGIN(ANY_MODE);
    (void)FMUstate;
    status = (fmi2Status)instance_state_size(inst, __func__, size);
    END;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size) {
    BEGIN(ANY_MODE);
    status = (fmi2Status)instance_serialize_state(inst, __func__, FMUstate,
                                                  (unsigned char *)serializedState, size);
    END;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    BEGIN(ANY_MODE);
    status = (fmi2Status)instance_deserialize_state(
        inst, __func__, (const unsigned char *)serializedState, size, FMUstate);
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
    BEGIN(mode_step);
    (void)noSetFMUStatePriorToCurrentPoint;
    status = (fmi2Status)instance_do_step(inst, __func__, currentCommunicationPoint,
                                          communicationStepSize);
    END;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    return not_supported(c, __func__, "fmi2DoStep never returns fmi2Pending");
}

/* FMI 2.0: a status the slave cannot provide is answered with fmi2Discard (not an error). */
static fmi2Status status_not_provided(Instance *inst, const char *function, fmi2StatusKind s) {
    instance_log(inst, status_discard, "logStatusWarning", "%s: status kind %d is not provided "
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
        *value = model_time(&inst->data);
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
        *value = fmi2False; /* the models never ask the master to stop */
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
