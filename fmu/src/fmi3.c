/*
 * FMI 3.0 Co-Simulation interface of TrailerTrain, written from the FMI 3.0 specification.
 *
 * A thin translation onto instance.c (names, types, statuses), like fmi2.c. What FMI 3.0 adds:
 * - n is a structural parameter (UInt64, fixed): set in Configuration Mode or, as fmpy does, in
 *   Instantiated; setting it resizes every array variable and returns the arrays to their start
 *   values. n_bodies = n + 1 sizes the per-body arrays (a Dimension cannot say n + 1).
 * - array variables: one value reference for all elements; nValues must match their sizes.
 * - no Event Mode, clocks, Model Exchange or Scheduled Execution: those functions are exported
 *   (importers look them all up) and return fmi3Error naming the capability flag.
 * Only the fmi3* functions are exported; everything else is static or hidden.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "fmi3Functions.h"
#include "instance.h"

#if FMI_VERSION != 3
#error "fmi3.c is the glue of the FMI 3.0 build (FMI_VERSION 3 in build_config.h)"
#endif

/* The value references and Int32 values are passed on to instance.c as unsigned and int. */
typedef char vr_is_unsigned[(sizeof(fmi3ValueReference) == sizeof(unsigned)) ? 1 : -1];
typedef char int32_is_int[(sizeof(fmi3Int32) == sizeof(int)) ? 1 : -1];

typedef struct {
    Instance core; /* first member: an fmi3Instance points to both */
    fmi3InstanceEnvironment environment;
    fmi3LogMessageCallback log_message; /* may be NULL: then nothing is logged */
} Fmi3Instance;

/*
 * Every fmi3 function that takes an instance starts with BEGIN(modes): the mode guard of
 * instance.c, naming the function by __func__. FAIL(...) logs "function: message", moves the
 * instance to the error state and returns fmi3Error; END returns the call's status.
 */
#define BEGIN(modes)                                                                            \
    Instance *const inst = (Instance *)instance;                                                \
    fmi3Status status = fmi3OK;                                                                 \
    if (!instance_allowed(inst, __func__, (modes))) {                                           \
        return fmi3Error;                                                                       \
    }
#define FAIL(...) return (fmi3Status)instance_fail(inst, __func__, __VA_ARGS__)
#define END return status
#define VRS ((const unsigned *)valueReferences)

static void log_to_importer(const Instance *core, Status status, const char *category,
                            const char *message) {
    const Fmi3Instance *inst = (const Fmi3Instance *)core;
    if (inst->log_message != NULL) {
        inst->log_message(inst->environment, (fmi3Status)status, category, message);
    }
}

static fmi3Status not_supported(fmi3Instance instance, const char *function, const char *why) {
    return (fmi3Status)instance_not_supported((Instance *)instance, function, why);
}

/* ---------------------------------------------------------------- life cycle */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    BEGIN(ERROR_MODES);
    status = (fmi3Status)instance_set_debug_logging(inst, __func__, loggingOn, nCategories,
                                                    categories);
    END;
}

static void log_before_instance(fmi3InstanceEnvironment environment,
                                fmi3LogMessageCallback log_message, const char *message) {
    if (log_message != NULL) {
        log_message(environment, fmi3Error, "logStatusError", message);
    }
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName,
                                          fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)instanceName;
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    log_before_instance(instanceEnvironment, logMessage, "fmi3InstantiateModelExchange: "
                        "TrailerTrain is a Co-Simulation FMU only (no <ModelExchange>)");
    return NULL;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible,
                                         fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
                                         fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    char msg[MSG_LEN];
    Fmi3Instance *inst;
    const char *name = instanceName ? instanceName : MODEL_IDENTIFIER;
    (void)visible;
    (void)earlyReturnAllowed; /* fmi3DoStep never returns early */
    (void)requiredIntermediateVariables; /* providesIntermediateUpdate = false */
    (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;
    if (eventModeUsed) {
        log_before_instance(instanceEnvironment, logMessage, "fmi3InstantiateCoSimulation: "
                            "eventModeUsed = true, but hasEventMode = false (TrailerTrain has no "
                            "events)");
        return NULL;
    }
    if (instantiationToken == NULL || strcmp(instantiationToken, MODEL_GUID) != 0) {
        snprintf(msg, sizeof(msg), "fmi3InstantiateCoSimulation: instantiationToken '%s' does "
                 "not match this binary's '%s' (the modelDescription.xml belongs to another "
                 "build)", instantiationToken ? instantiationToken : "(null)", MODEL_GUID);
        log_before_instance(instanceEnvironment, logMessage, msg);
        return NULL;
    }
    inst = (Fmi3Instance *)instance_new(sizeof(Fmi3Instance), name, resourcePath,
                                        log_to_importer, loggingOn, msg, sizeof(msg));
    if (inst == NULL) {
        char refused[MSG_LEN + 40];
        snprintf(refused, sizeof(refused), "fmi3InstantiateCoSimulation: %s", msg);
        log_before_instance(instanceEnvironment, logMessage, refused);
        return NULL;
    }
    inst->environment = instanceEnvironment;
    inst->log_message = logMessage;
    return inst;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName,
                                               fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible,
                                               fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage,
                                               fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName;
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    (void)clockUpdate;
    (void)lockPreemption;
    (void)unlockPreemption;
    log_before_instance(instanceEnvironment, logMessage, "fmi3InstantiateScheduledExecution: "
                        "TrailerTrain is a Co-Simulation FMU only (no <ScheduledExecution>)");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) {
    instance_free((Instance *)instance);
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    BEGIN(mode_instantiated | mode_step);
    if (inst->mode != mode_instantiated) {
        FAIL("no Reconfiguration Mode: n is a fixed structural parameter (set it before "
             "initialization)");
    }
    inst->mode = mode_configuration;
    END;
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    BEGIN(mode_configuration);
    status = (fmi3Status)instance_end_configuration(inst, __func__);
    if (status == fmi3OK) {
        inst->mode = mode_instantiated;
    }
    END;
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    BEGIN(mode_instantiated);
    (void)toleranceDefined; /* fixed substeps: no tolerance to honour */
    (void)tolerance;
    if (!isfinite(startTime)) {
        FAIL("startTime = %g: must be finite", startTime);
    }
    if (stopTimeDefined && !(stopTime >= startTime)) {
        FAIL("stopTime = %g: must be >= startTime = %g", stopTime, startTime);
    }
    /* n may have been set in Instantiated (fmpy does): the structure is final now */
    if (instance_end_configuration(inst, __func__) != status_ok) {
        return fmi3Error;
    }
    model_set_start_time(&inst->data, startTime);
    inst->stop_time_defined = stopTimeDefined;
    inst->stop_time = stopTime;
    inst->mode = mode_initialization;
    END;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    BEGIN(mode_initialization);
    status = (fmi3Status)instance_exit_initialization(inst, __func__); /* to Step Mode */
    END;
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    BEGIN(mode_step);
    inst->mode = mode_terminated;
    END;
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    BEGIN(ERROR_MODES);
    instance_reset(inst);
    END;
}

/* ---------------------------------------------------------------- get and set */

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
    BEGIN(ERROR_MODES);
    status = (fmi3Status)instance_get_real(inst, __func__, VRS, nValueReferences, values,
                                           nValues);
    END;
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Int32 values[], size_t nValues) {
    BEGIN(ERROR_MODES);
    status = (fmi3Status)instance_get_integer(inst, __func__, VRS, nValueReferences,
                                              (int *)values, nValues);
    END;
}

fmi3Status fmi3GetUInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, fmi3UInt64 values[], size_t nValues) {
    BEGIN(ERROR_MODES);
    status = (fmi3Status)instance_get_uint64(inst, __func__, VRS, nValueReferences, values,
                                             nValues);
    END;
}

fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Boolean values[], size_t nValues) {
    BEGIN(ERROR_MODES);
    status = (fmi3Status)instance_get_boolean(inst, __func__, VRS, nValueReferences, values,
                                              nValues);
    END;
}

/* Inputs in every mode before Terminated; parameters and structural parameters are refused
   by variables.c outside their phase, naming the variable. */
#define SET_MODES (mode_instantiated | mode_configuration | mode_initialization | mode_step)

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[], size_t nValues) {
    BEGIN(SET_MODES);
    status = (fmi3Status)instance_set_real(inst, __func__, VRS, nValueReferences, values,
                                           nValues);
    END;
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Int32 values[], size_t nValues) {
    BEGIN(SET_MODES);
    status = (fmi3Status)instance_set_integer(inst, __func__, VRS, nValueReferences,
                                              (const int *)values, nValues);
    END;
}

fmi3Status fmi3SetUInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const fmi3UInt64 values[], size_t nValues) {
    BEGIN(SET_MODES | mode_terminated);
    status = (fmi3Status)instance_set_uint64(inst, __func__, VRS, nValueReferences, values,
                                             nValues);
    END;
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Boolean values[], size_t nValues) {
    BEGIN(SET_MODES);
    status = (fmi3Status)instance_set_boolean(inst, __func__, VRS, nValueReferences, values,
                                              nValues);
    END;
}

/* Types TrailerTrain has no variables of: a call with value references is an error. */
#define NO_VARIABLES(FUNCTION, VALUE_TYPE, TYPE_NAME, MODES)                                    \
    fmi3Status FUNCTION(fmi3Instance instance, const fmi3ValueReference valueReferences[],      \
                        size_t nValueReferences, VALUE_TYPE values[], size_t nValues) {         \
        BEGIN(MODES);                                                                           \
        (void)values;                                                                           \
        (void)nValues;                                                                          \
        if (nValueReferences > 0) {                                                             \
            FAIL("value reference %u: TrailerTrain has no " TYPE_NAME " variables",             \
                 (unsigned)(valueReferences ? valueReferences[0] : 0));                         \
        }                                                                                       \
        END;                                                                                    \
    }

NO_VARIABLES(fmi3GetFloat32, fmi3Float32, "Float32", ERROR_MODES)
NO_VARIABLES(fmi3GetInt8, fmi3Int8, "Int8", ERROR_MODES)
NO_VARIABLES(fmi3GetUInt8, fmi3UInt8, "UInt8", ERROR_MODES)
NO_VARIABLES(fmi3GetInt16, fmi3Int16, "Int16", ERROR_MODES)
NO_VARIABLES(fmi3GetUInt16, fmi3UInt16, "UInt16", ERROR_MODES)
NO_VARIABLES(fmi3GetUInt32, fmi3UInt32, "UInt32", ERROR_MODES)
NO_VARIABLES(fmi3GetInt64, fmi3Int64, "Int64", ERROR_MODES)
NO_VARIABLES(fmi3GetString, fmi3String, "String", ERROR_MODES)
NO_VARIABLES(fmi3SetFloat32, const fmi3Float32, "Float32", SET_MODES)
NO_VARIABLES(fmi3SetInt8, const fmi3Int8, "Int8", SET_MODES)
NO_VARIABLES(fmi3SetUInt8, const fmi3UInt8, "UInt8", SET_MODES)
NO_VARIABLES(fmi3SetInt16, const fmi3Int16, "Int16", SET_MODES)
NO_VARIABLES(fmi3SetUInt16, const fmi3UInt16, "UInt16", SET_MODES)
NO_VARIABLES(fmi3SetUInt32, const fmi3UInt32, "UInt32", SET_MODES)
NO_VARIABLES(fmi3SetInt64, const fmi3Int64, "Int64", SET_MODES)
NO_VARIABLES(fmi3SetString, const fmi3String, "String", SET_MODES)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, size_t valueSizes[], fmi3Binary values[],
                         size_t nValues) {
    BEGIN(ERROR_MODES);
    (void)valueSizes;
    (void)values;
    (void)nValues;
    if (nValueReferences > 0) {
        FAIL("value reference %u: TrailerTrain has no Binary variables",
             (unsigned)(valueReferences ? valueReferences[0] : 0));
    }
    END;
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const size_t valueSizes[],
                         const fmi3Binary values[], size_t nValues) {
    BEGIN(SET_MODES);
    (void)valueSizes;
    (void)values;
    (void)nValues;
    if (nValueReferences > 0) {
        FAIL("value reference %u: TrailerTrain has no Binary variables",
             (unsigned)(valueReferences ? valueReferences[0] : 0));
    }
    END;
}

/* ---------------------------------------------------------------- FMU state */

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    BEGIN(ANY_MODE);
    status = (fmi3Status)instance_get_state(inst, __func__, FMUState);
    END;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    BEGIN(ERROR_MODES);
    status = (fmi3Status)instance_set_state(inst, __func__, FMUState);
    END;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    BEGIN(ERROR_MODES);
    status = (fmi3Status)instance_free_state(inst, __func__, FMUState);
    END;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState,
                                      size_t *size) {
    BEGIN(ANY_MODE);
    (void)FMUState;
    status = (fmi3Status)instance_state_size(inst, __func__, size);
    END;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState,
                                 fmi3Byte serializedState[], size_t size) {
    BEGIN(ANY_MODE);
    status = (fmi3Status)instance_serialize_state(inst, __func__, FMUState, serializedState,
                                                  size);
    END;
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[],
                                   size_t size, fmi3FMUState *FMUState) {
    BEGIN(ANY_MODE);
    status = (fmi3Status)instance_deserialize_state(inst, __func__, serializedState, size,
                                                    FMUState);
    END;
}

/* ---------------------------------------------------------------- Co-Simulation */

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    double before;
    BEGIN(mode_step);
    (void)noSetFMUStatePriorToCurrentPoint;
    before = model_time(&inst->data);
    status = (fmi3Status)instance_do_step(inst, __func__, currentCommunicationPoint,
                                          communicationStepSize);
    if (eventHandlingNeeded != NULL) {
        *eventHandlingNeeded = false;
    }
    if (terminateSimulation != NULL) {
        *terminateSimulation = false; /* the model never asks the importer to stop */
    }
    if (earlyReturn != NULL) {
        *earlyReturn = false;
    }
    if (lastSuccessfulTime != NULL) {
        *lastSuccessfulTime = (status == fmi3OK) ? model_time(&inst->data) : before;
    }
    END;
}

/* ---------------------------------------------------------------- what TrailerTrain has not */

/*
 * A function of a capability TrailerTrain does not have (its modelDescription says so: no Event
 * Mode, clocks, dependencies, derivatives, Model Exchange or Scheduled Execution). Importers look
 * every function up, so each is exported, defined by one line: NOT_SUPPORTED(name, (its
 * parameters), why). It logs "name: not supported (why)", moves the instance to the error state
 * and returns fmi3Error. The parameters besides the instance are unused by design.
 */
#define NOT_SUPPORTED(FUNCTION, PARAMETERS, WHY)                                                \
    fmi3Status FUNCTION PARAMETERS {                                                            \
        return not_supported(instance, #FUNCTION, WHY);                                         \
    }
#define NO_CLOCKS MODEL_IDENTIFIER " has no clocks"
#define ME_ONLY "Model Exchange: " MODEL_IDENTIFIER " is a Co-Simulation FMU only"
#define VRS_IN const fmi3ValueReference valueReferences[], size_t nValueReferences

#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-parameter"
#endif

NOT_SUPPORTED(fmi3EnterEventMode, (fmi3Instance instance), "hasEventMode = false")
NOT_SUPPORTED(fmi3EvaluateDiscreteStates, (fmi3Instance instance),
              "providesEvaluateDiscreteStates = false")
NOT_SUPPORTED(fmi3UpdateDiscreteStates,
              (fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
               fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
               fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
               fmi3Float64 *nextEventTime),
              "hasEventMode = false")
NOT_SUPPORTED(fmi3EnterStepMode, (fmi3Instance instance),
              "hasEventMode = false: fmi3ExitInitializationMode enters Step Mode")

NOT_SUPPORTED(fmi3GetClock, (fmi3Instance instance, VRS_IN, fmi3Clock values[]), NO_CLOCKS)
NOT_SUPPORTED(fmi3SetClock, (fmi3Instance instance, VRS_IN, const fmi3Clock values[]), NO_CLOCKS)
NOT_SUPPORTED(fmi3GetIntervalDecimal,
              (fmi3Instance instance, VRS_IN, fmi3Float64 intervals[],
               fmi3IntervalQualifier qualifiers[]), NO_CLOCKS)
NOT_SUPPORTED(fmi3GetIntervalFraction,
              (fmi3Instance instance, VRS_IN, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
               fmi3IntervalQualifier qualifiers[]), NO_CLOCKS)
NOT_SUPPORTED(fmi3GetShiftDecimal, (fmi3Instance instance, VRS_IN, fmi3Float64 shifts[]),
              NO_CLOCKS)
NOT_SUPPORTED(fmi3GetShiftFraction,
              (fmi3Instance instance, VRS_IN, fmi3UInt64 counters[], fmi3UInt64 resolutions[]),
              NO_CLOCKS)
NOT_SUPPORTED(fmi3SetIntervalDecimal,
              (fmi3Instance instance, VRS_IN, const fmi3Float64 intervals[]), NO_CLOCKS)
NOT_SUPPORTED(fmi3SetIntervalFraction,
              (fmi3Instance instance, VRS_IN, const fmi3UInt64 counters[],
               const fmi3UInt64 resolutions[]), NO_CLOCKS)
NOT_SUPPORTED(fmi3SetShiftDecimal, (fmi3Instance instance, VRS_IN, const fmi3Float64 shifts[]),
              NO_CLOCKS)
NOT_SUPPORTED(fmi3SetShiftFraction,
              (fmi3Instance instance, VRS_IN, const fmi3UInt64 counters[],
               const fmi3UInt64 resolutions[]), NO_CLOCKS)

NOT_SUPPORTED(fmi3GetNumberOfVariableDependencies,
              (fmi3Instance instance, fmi3ValueReference valueReference, size_t *nDependencies),
              "providesPerElementDependencies = false")
NOT_SUPPORTED(fmi3GetVariableDependencies,
              (fmi3Instance instance, fmi3ValueReference dependent,
               size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
               size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
               size_t nDependencies),
              "providesPerElementDependencies = false")
NOT_SUPPORTED(fmi3GetDirectionalDerivative,
              (fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
               const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
               size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity),
              "providesDirectionalDerivatives = false")
NOT_SUPPORTED(fmi3GetAdjointDerivative,
              (fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
               const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
               size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity),
              "providesAdjointDerivatives = false")
NOT_SUPPORTED(fmi3GetOutputDerivatives,
              (fmi3Instance instance, VRS_IN, const fmi3Int32 orders[], fmi3Float64 values[],
               size_t nValues), "maxOutputDerivativeOrder = 0")

NOT_SUPPORTED(fmi3EnterContinuousTimeMode, (fmi3Instance instance), ME_ONLY)
NOT_SUPPORTED(fmi3CompletedIntegratorStep,
              (fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
               fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation), ME_ONLY)
NOT_SUPPORTED(fmi3SetTime, (fmi3Instance instance, fmi3Float64 time), ME_ONLY)
NOT_SUPPORTED(fmi3SetContinuousStates,
              (fmi3Instance instance, const fmi3Float64 continuousStates[],
               size_t nContinuousStates), ME_ONLY)
NOT_SUPPORTED(fmi3GetContinuousStateDerivatives,
              (fmi3Instance instance, fmi3Float64 derivatives[], size_t nContinuousStates),
              ME_ONLY)
NOT_SUPPORTED(fmi3GetEventIndicators,
              (fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators),
              ME_ONLY)
NOT_SUPPORTED(fmi3GetContinuousStates,
              (fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates),
              ME_ONLY)
NOT_SUPPORTED(fmi3GetNominalsOfContinuousStates,
              (fmi3Instance instance, fmi3Float64 nominals[], size_t nContinuousStates), ME_ONLY)
NOT_SUPPORTED(fmi3GetNumberOfEventIndicators,
              (fmi3Instance instance, size_t *nEventIndicators), ME_ONLY)
NOT_SUPPORTED(fmi3GetNumberOfContinuousStates,
              (fmi3Instance instance, size_t *nContinuousStates), ME_ONLY)

NOT_SUPPORTED(fmi3ActivateModelPartition,
              (fmi3Instance instance, fmi3ValueReference clockReference,
               fmi3Float64 activationTime), MODEL_IDENTIFIER " has no <ScheduledExecution>")

#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif
