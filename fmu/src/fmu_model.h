/*
 * What a model gives the FMI glue. Both FMUs of pushtrain are built on one glue, instance.c under
 * fmi2.c (or fmi3.c): the plant TrailerTrain (model.h: model.c, variables.c) and the
 * BackwardController (ctrl_instance.h: ctrl_instance.c). The glue keeps the modes, the logging,
 * the checks the standard asks for (times, steps, stop time) and the FMU states; the model keeps
 * its variables, start values, initialization and step, through the functions below.
 *
 * The build's generated build_config.h names the model: FMI_VERSION, MODEL_IDENTIFIER,
 * MODEL_GUID and MODEL_HEADER, the model's header. That header defines struct ModelData (plain
 * data the instance embeds) and MODEL_CAN_GET_AND_SET_STATE (1: ModelData is a copyable state,
 * the glue provides FMU states; 0: they are not supported).
 *
 * Every function that can fail writes "what is wrong" into msg (len bytes) and returns false;
 * the glue prefixes the name of the FMI function and moves the instance to its error state.
 */
#ifndef PUSHTRAIN_FMU_MODEL_H
#define PUSHTRAIN_FMU_MODEL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* generated per build: FMI_VERSION, MODEL_IDENTIFIER, MODEL_GUID, MODEL_HEADER */
#include "build_config.h"

#if !defined(FMI_VERSION) || !defined(MODEL_IDENTIFIER) || !defined(MODEL_GUID) \
    || !defined(MODEL_HEADER)
#error "build_config.h must define FMI_VERSION, MODEL_IDENTIFIER, MODEL_GUID and MODEL_HEADER"
#endif

#if defined(__GNUC__)
#define PT_INTERNAL __attribute__((visibility("hidden")))
#else
#define PT_INTERNAL
#endif

typedef struct ModelData ModelData; /* defined by the model's header */

/* Where the instance is in its life cycle, as far as the model cares: what can be set, and
   whether outputs follow the start values (before initialization ends) or are the last ones
   (after an error). */
typedef enum {
    phase_instantiated,   /* parameters, inputs and the structural parameters */
    phase_configuration,  /* FMI 3.0 Configuration Mode: only the structural parameters */
    phase_initialization, /* parameters and inputs */
    phase_running,        /* after initialization (FMI 2.0 StepComplete): inputs */
    phase_terminated,     /* after fmi2Terminate / fmi3Terminate */
    phase_error           /* after an error: only reads, for diagnostics */
} ModelPhase;

/* Life cycle. model_instantiate runs once, on zeroed data, before model_set_defaults: it may
   read the FMU's resources (resource_location: the importer's URI or path, possibly NULL) and
   refuse, having released what it took. model_free releases what it took. */
PT_INTERNAL bool model_instantiate(ModelData *m, const char *resource_location, char *msg,
                                   size_t len);
PT_INTERNAL void model_free(ModelData *m);
/* Every variable at its start value, the memory of earlier steps forgotten (fmi2Reset). */
PT_INTERNAL void model_set_defaults(ModelData *m);
/* The time [s] of the experiment's start (fmi2SetupExperiment) and the model's time now. */
PT_INTERNAL void model_set_start_time(ModelData *m, double start_time);
PT_INTERNAL double model_time(const ModelData *m);
/* When initialization ends: checks the parameters (and what else must hold), then derives
   everything from them (importers may set parameters only after entering initialization). */
PT_INTERNAL bool model_exit_initialization(ModelData *m, char *msg, size_t len);
/* One communication step from t by h [s]; the glue has checked h > 0 and t against the model's
   time within tolerance [s]. Moves the model's time to the end of the step. */
PT_INTERNAL bool model_do_step(ModelData *m, double t, double h, double tolerance, char *msg,
                               size_t len);

/* Get and set by value reference. A value reference stands for one value (a scalar; an element
   x[i] in FMI 2.0) or for a whole array (FMI 3.0). The functions move its values through
   values[*index ..] (at most n_values in all) and advance *index. Outputs are read as last
   computed: make them current first (model_update_outputs) when model_needs_outputs(vr). */
PT_INTERNAL bool model_needs_outputs(const ModelData *m, unsigned vr);
PT_INTERNAL bool model_update_outputs(ModelData *m, ModelPhase phase, char *msg, size_t len);
/* model_get_real for vr[0..nvr) (the plant looks up the storage of an FMI 2.0 array once for a
   run of its elements). */
PT_INTERNAL bool model_get_reals(const ModelData *m, const unsigned vr[], size_t nvr,
                                 double values[], size_t n_values, size_t *index, char *msg,
                                 size_t len);
PT_INTERNAL bool model_get_integer(const ModelData *m, unsigned vr, int values[], size_t n_values,
                                   size_t *index, char *msg, size_t len);
PT_INTERNAL bool model_get_boolean(const ModelData *m, unsigned vr, bool values[],
                                   size_t n_values, size_t *index, char *msg, size_t len);
PT_INTERNAL bool model_set_real(ModelData *m, unsigned vr, const double values[], size_t n_values,
                                size_t *index, ModelPhase phase, char *msg, size_t len);
PT_INTERNAL bool model_set_integer(ModelData *m, unsigned vr, const int values[],
                                   size_t n_values, size_t *index, ModelPhase phase, char *msg,
                                   size_t len);
PT_INTERNAL bool model_set_boolean(ModelData *m, unsigned vr, const bool values[],
                                   size_t n_values, size_t *index, ModelPhase phase, char *msg,
                                   size_t len);

/* Called by the FMI 3.0 glue only (an FMI 2.0 model need not define them): the structural
   parameters (UInt64); setting n resizes the model at once, after a range check; n_bodies is
   remembered and must equal n + 1 when configuration ends. */
PT_INTERNAL bool model_get_uint64(const ModelData *m, unsigned vr, uint64_t values[],
                                  size_t n_values, size_t *index, char *msg, size_t len);
PT_INTERNAL bool model_set_uint64(ModelData *m, unsigned vr, const uint64_t values[],
                                  size_t n_values, size_t *index, ModelPhase phase, char *msg,
                                  size_t len);
/* When configuration ends: the structural parameters agree. */
PT_INTERNAL bool model_check_structure(ModelData *m, char *msg, size_t len);

#endif
