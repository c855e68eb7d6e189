/*
 * What the FMI 2.0 glue (fmi2.c) and the FMI 3.0 glue (fmi3.c) share: an instance (model data,
 * mode, log settings) and the parts of the API whose rules are the same in both standards: mode
 * guards, logging, get/set by value reference, initialization, the step, FMU states. The glue
 * files translate names and types only. Statuses are numbered alike in both standards. The
 * model is any that implements fmu_model.h: both FMUs of pushtrain (TrailerTrain and the
 * BackwardController) are built on this glue.
 *
 * Every call that fails logs "function: what is wrong" (function is the fmi2/fmi3 name) and moves
 * the instance to mode_error, where only getters (for diagnostics), setting a saved FMU state,
 * reset and free are allowed.
 */
#ifndef TRAILERTRAIN_INSTANCE_H
#define TRAILERTRAIN_INSTANCE_H

#include "fmu_model.h"
#include MODEL_HEADER /* the model's own header: struct ModelData */

typedef enum {
    status_ok = 0,
    status_warning = 1,
    status_discard = 2,
    status_error = 3,
    status_fatal = 4
} Status;

typedef enum {
    mode_instantiated = 1,
    mode_configuration = 2, /* FMI 3.0 Configuration Mode */
    mode_initialization = 4,
    mode_step = 8,          /* FMI 2.0 StepComplete, FMI 3.0 Step Mode */
    mode_terminated = 16,
    mode_error = 32
} Mode;

#define SETUP_MODES (mode_instantiated | mode_initialization)
#define ANY_MODE (mode_instantiated | mode_configuration | mode_initialization | mode_step \
                  | mode_terminated)
#define ERROR_MODES (ANY_MODE | mode_error)
#define MSG_LEN 512

typedef struct Instance Instance;

/* The glue's logger: hands one finished message to the importer's callback. */
typedef void (*LogSink)(const Instance *inst, Status status, const char *category,
                        const char *message);

/* The glue embeds this as the first member of its own instance type (which adds the
   importer's callbacks). */
struct Instance {
    ModelData data;
    Mode mode;
    bool stop_time_defined; /* no step may end after stop_time */
    double stop_time;
    char *instance_name;
    LogSink sink;
    bool logging_on;
    bool log_debug;    /* category logDebug */
    bool log_errors;   /* category logStatusError */
    bool log_warnings; /* category logStatusWarning */
};

/* Allocates size bytes (the glue's instance type) with the model instantiated
   (model_instantiate, given the FMU's resource_location) and at its start values, in
   mode_instantiated; NULL with a message in msg when out of memory or the model refuses. */
PT_INTERNAL Instance *instance_new(size_t size, const char *name, const char *resource_location,
                                   LogSink sink, bool logging_on, char *msg, size_t len);
PT_INTERNAL void instance_free(Instance *inst);
/* Back to the start values and mode_instantiated (fmi2Reset, fmi3Reset). */
PT_INTERNAL void instance_reset(Instance *inst);

PT_INTERNAL void instance_log(const Instance *inst, Status status, const char *category,
                              const char *fmt, ...);
/* Logs "function: message", moves the instance to mode_error and returns status_error. */
PT_INTERNAL Status instance_fail(Instance *inst, const char *function, const char *fmt, ...);
/* The call is allowed in the instance's mode (else it fails, naming the mode). */
PT_INTERNAL bool instance_allowed(Instance *inst, const char *function, int modes);
/* A function whose capability flag in the XML says it is not provided: an error. */
PT_INTERNAL Status instance_not_supported(Instance *inst, const char *function, const char *why);
PT_INTERNAL Status instance_set_debug_logging(Instance *inst, const char *function,
                                              bool logging_on, size_t n_categories,
                                              const char *const categories[]);

/* Get and set by value reference: vr[0..nvr) with their values in values[0..n_values), which
   must hold exactly as many values as the variables have (1 per scalar, n or n + 1 per FMI 3.0
   array). Outputs are made current at most once per call. */
PT_INTERNAL Status instance_get_real(Instance *inst, const char *function, const unsigned vr[],
                                     size_t nvr, double values[], size_t n_values);
PT_INTERNAL Status instance_get_integer(Instance *inst, const char *function,
                                        const unsigned vr[], size_t nvr, int values[],
                                        size_t n_values);
PT_INTERNAL Status instance_get_boolean(Instance *inst, const char *function,
                                        const unsigned vr[], size_t nvr, bool values[],
                                        size_t n_values);
PT_INTERNAL Status instance_get_uint64(Instance *inst, const char *function, const unsigned vr[],
                                       size_t nvr, uint64_t values[], size_t n_values);
PT_INTERNAL Status instance_set_real(Instance *inst, const char *function, const unsigned vr[],
                                     size_t nvr, const double values[], size_t n_values);
PT_INTERNAL Status instance_set_integer(Instance *inst, const char *function,
                                        const unsigned vr[], size_t nvr, const int values[],
                                        size_t n_values);
PT_INTERNAL Status instance_set_boolean(Instance *inst, const char *function,
                                        const unsigned vr[], size_t nvr, const bool values[],
                                        size_t n_values);
PT_INTERNAL Status instance_set_uint64(Instance *inst, const char *function, const unsigned vr[],
                                       size_t nvr, const uint64_t values[], size_t n_values);

/* Ends configuration (fmi3ExitConfigurationMode, fmi3EnterInitializationMode): n_bodies agrees
   with n. */
PT_INTERNAL Status instance_end_configuration(Instance *inst, const char *function);
/* The model checks its parameters and derives everything from them (model_exit_initialization:
   some importers set parameters only after entering initialization). Moves to mode_step. */
PT_INTERNAL Status instance_exit_initialization(Instance *inst, const char *function);
/* One communication step from t by h [s]: checks h, t against the FMU's time (within a
   tolerance) and the stop time, then the model steps to t + h (model_do_step). */
PT_INTERNAL Status instance_do_step(Instance *inst, const char *function, double t, double h);

/* FMU states: a copy of the model data and the mode (plain data, so serializing is a copy);
   not supported (an error) for a model whose MODEL_CAN_GET_AND_SET_STATE is 0. */
PT_INTERNAL Status instance_get_state(Instance *inst, const char *function, void **state);
PT_INTERNAL Status instance_set_state(Instance *inst, const char *function, const void *state);
PT_INTERNAL Status instance_free_state(Instance *inst, const char *function, void **state);
PT_INTERNAL Status instance_state_size(Instance *inst, const char *function, size_t *size);
PT_INTERNAL Status instance_serialize_state(Instance *inst, const char *function,
                                            const void *state, unsigned char *bytes,
                                            size_t size);
PT_INTERNAL Status instance_deserialize_state(Instance *inst, const char *function,
                                              const unsigned char *bytes, size_t size,
                                              void **state);

#endif
