/*
 * Get and set TrailerTrain's variables by value reference, independent of the FMI version.
 *
 * The numbering, names, types and causalities come from variables.h, which the builder generates
 * from fmu/variables.py; this file only says where each variable lives in ModelData. The switches
 * over the generated enums have no default, so -Wswitch names any variable left out here.
 * Outputs are read as last computed: the caller makes them current first (model_needs_outputs).
 *
 * A value reference stands for `count` values: 1 for a scalar and for an element x[i] of the FMI
 * 2.0 build, the array's length at the instance's n for an FMI 3.0 array (x: x[0] .. x[n]).
 * The get/set functions move them through values[*index ..] and advance *index.
 * time and n_bodies exist in FMI 3.0 only (#if FMI_VERSION == 3).
 */
#include <math.h>
#include <stdio.h>

#include "model.h"
#include "variables.h"

typedef struct {
    const VarInfo *info;
    int block; /* 0 for scalars */
    int first; /* body index i of the first value; the scalar's vr for scalars */
    int count; /* number of values */
} VarRef;

static inline bool decode(const ModelData *m, unsigned vr, VarRef *out) {
    const unsigned block = vr / VR_STRIDE, index = vr % VR_STRIDE;
    const VarInfo *info;
    if (block >= BLOCK_END) {
        return false;
    }
    info = (block == 0) ? (index < SCALAR_VR_END ? &scalar_info[index] : NULL) : &block_info[block];
    if (info == NULL || info->name == NULL) {
        return false;
    }
    out->info = info;
    out->block = (int)block;
    out->first = (int)index;
    out->count = 1;
    if (block != 0) {
#if FMI_VERSION == 3
        if (index != 0) { /* FMI 3.0: one array variable per block */
            return false;
        }
        out->first = info->first;
        out->count = m->n + info->last_offset - info->first + 1;
#else
        if ((int)index < info->first || (int)index > m->n + info->last_offset) {
            return false;
        }
#endif
    }
    return true;
}

/* "name" of a scalar or an FMI 3.0 array, "name[i]" of element k of r (body index i). */
static const char *element_name(VarRef r, int k, char *buffer, size_t len) {
    if (r.block == 0 || (FMI_VERSION == 3 && k < 0)) {
        snprintf(buffer, len, "%s", r.info->name);
    } else {
        snprintf(buffer, len, "%s[%d]", r.info->name, r.first + (k < 0 ? 0 : k));
    }
    return buffer;
}

const char *model_variable_name(const ModelData *m, unsigned vr, char *buffer, size_t len) {
    VarRef r = {NULL, 0, 0, 0}; /* set by decode; zeroed for gcc's flow analysis */
    if (!decode(m, vr, &r)) {
        snprintf(buffer, len, "(unknown value reference %u)", vr);
        return buffer;
    }
    return element_name(r, -1, buffer, len);
}

bool model_needs_outputs(const ModelData *m, unsigned vr) {
    VarRef r = {NULL, 0, 0, 0}; /* set by decode; zeroed for gcc's flow analysis */
    return decode(m, vr, &r)
           && (r.info->causality == var_output || r.info->causality == var_calculated_parameter);
}

/* ---------------------------------------------------------------- where each variable lives */

static double *real_scalar(ModelData *m, enum ScalarVr vr) {
    switch (vr) {
#if FMI_VERSION == 3
    case vr_time: return &m->time;
    case vr_n_bodies: break; /* not Real */
#endif
    case vr_v_cmd: return &m->v_cmd;
    case vr_w_cmd: return &m->w_cmd;
    case vr_push_x: return &m->push_x;
    case vr_push_y: return &m->push_y;
    case vr_g: return &m->g;
    case vr_robot_tau: return &m->robot_tau;
    case vr_robot_acc_max: return &m->robot_acc_max;
    case vr_robot_alpha_max: return &m->robot_alpha_max;
    case vr_phi_max: return &m->phi_max;
    case vr_x0_start: return &m->x0_start;
    case vr_y0_start: return &m->y0_start;
    case vr_v_start: return &m->v_start;
    case vr_w_start: return &m->w_start;
    case vr_max_substep: return &m->max_substep;
    case vr_slip_substep: return &m->slip_substep;
    case vr_slip_mode: case vr_n: case vr_jackknifed: break; /* not Real */
    }
    return NULL;
}

static double *real_element(ModelData *m, enum Block block, int i) {
    switch (block) {
    case blk_front: return &m->front[i];
    case blk_rear: return &m->rear[i];
    case blk_mass: return &m->mass[i];
    case blk_inertia: return &m->inertia[i];
    case blk_payload: return &m->payload[i];
    case blk_mu: return &m->mu[i];
    case blk_theta_start: return &m->theta_start[i];
    case blk_x: return &m->x[i];
    case blk_y: return &m->y[i];
    case blk_theta: return &m->q[IX_THETA + i];
    case blk_phi: return &m->phi[i];
    case blk_v: return &m->v[i];
    case blk_w: return &m->w[i];
    case blk_F_lat: return &m->F_lat[i];
    case blk_F_lat_max: return &m->F_lat_max[i];
    case blk_slide: return &m->slide[i];
    case blk_hitch_fx: return &m->hitch_fx[i];
    case blk_hitch_fy: return &m->hitch_fy[i];
    case blk_slide_speed: return &m->slide_speed[i];
    case blk_slipping: break; /* not Real */
    }
    return NULL;
}

/* value k (0..count-1) of the Real variable r */
static double *real_value(ModelData *m, VarRef r, int k) {
    return (r.block == 0) ? real_scalar(m, (enum ScalarVr)r.first)
                          : real_element(m, (enum Block)r.block, r.first + k);
}

static const char *const type_names[] = {"Real", "Integer", "Boolean", "UInt64"};

/* Why vr is not a known variable of type `type` (the slow path of check_type). */
static bool type_error(const ModelData *m, unsigned vr, VarType type, char *msg, size_t len) {
    char name[64];
    VarRef r = {NULL, 0, 0, 0}; /* set by decode; zeroed for gcc's flow analysis */
    if (!decode(m, vr, &r)) {
        snprintf(msg, len, "unknown value reference %u", vr);
    } else {
        snprintf(msg, len, "%s (value reference %u) is a%s %s, not a%s %s",
                 model_variable_name(m, vr, name, sizeof(name)), vr,
                 r.info->type == var_integer ? "n" : "", type_names[r.info->type],
                 type == var_integer ? "n" : "", type_names[type]);
    }
    return false;
}

/* r is a known variable of type `type`; else writes why not into msg. */
static inline bool check_type(const ModelData *m, unsigned vr, VarType type, VarRef *r,
                              char *msg, size_t len) {
    if (decode(m, vr, r) && r->info->type == type) {
        return true;
    }
    return type_error(m, vr, type, msg, len);
}

/* Why values[index ..] has no room for r's values (the slow path of check_room). */
static bool room_error(const ModelData *m, VarRef r, size_t n_values, size_t index, char *msg,
                       size_t len) {
    char name[64];
    snprintf(msg, len, "%s has %d value%s (n = %d) but nValues = %u leaves room for %u",
             element_name(r, -1, name, sizeof(name)), r.count, r.count == 1 ? "" : "s", m->n,
             (unsigned)n_values, (unsigned)(index <= n_values ? n_values - index : 0));
    return false;
}

/* values[*index ..] has room for r's values; else writes why not into msg. */
static inline bool check_room(const ModelData *m, VarRef r, size_t n_values, size_t index,
                              char *msg, size_t len) {
    if (index <= n_values && (size_t)r.count <= n_values - index) {
        return true;
    }
    return room_error(m, r, n_values, index, msg, len);
}

/* ---------------------------------------------------------------- get */

bool model_get_real(const ModelData *m, unsigned vr, double values[], size_t n_values,
                    size_t *index, char *msg, size_t len) {
    VarRef r = {NULL, 0, 0, 0}; /* set by decode; zeroed for gcc's flow analysis */
    const double *p;
    int k;
    if (!check_type(m, vr, var_real, &r, msg, len)
        || !check_room(m, r, n_values, *index, msg, len)) {
        return false;
    }
    p = real_value((ModelData *)m, r, 0); /* only read; an array's values follow its first */
    if (p == NULL) { /* a Real in variables.py that has no place in ModelData */
        snprintf(msg, len, "%s has no storage in this build", r.info->name);
        return false;
    }
    for (k = 0; k < r.count; k++) {
        values[(*index)++] = p[k];
    }
    return true;
}

bool model_get_reals(const ModelData *m, const unsigned vr[], size_t nvr, double values[],
                     size_t n_values, size_t *index, char *msg, size_t len) {
    const double *base = NULL; /* element 0 of the FMI 2.0 Real array read last, if any */
    unsigned block = 0;
    int lo = 0, hi = -1; /* its valid element indices */
    size_t k;
    for (k = 0; k < nvr; k++) {
        const unsigned i = vr[k] % VR_STRIDE;
        if (base != NULL && vr[k] / VR_STRIDE == block && (int)i >= lo && (int)i <= hi
            && *index < n_values) {
            values[(*index)++] = base[i]; /* another element of the same array */
            continue;
        }
        if (!model_get_real(m, vr[k], values, n_values, index, msg, len)) {
            return false;
        }
        block = vr[k] / VR_STRIDE;
        base = NULL;
        if (FMI_VERSION == 2 && block != 0) { /* an element of a Real array (checked above) */
            base = real_element((ModelData *)m, (enum Block)block, 0); /* only read */
            lo = block_info[block].first;
            hi = m->n + block_info[block].last_offset;
        }
    }
    return true;
}

/* the Integer variable r (a scalar) */
static bool integer_value(const ModelData *m, VarRef r, int *value) {
    switch ((enum ScalarVr)r.first) {
    case vr_n: *value = m->n; return true; /* FMI 2.0: a constant output */
    case vr_slip_mode: *value = m->slip_mode; return true;
    default: return false;
    }
}

bool model_get_integer(const ModelData *m, unsigned vr, int values[], size_t n_values,
                       size_t *index, char *msg, size_t len) {
    VarRef r = {NULL, 0, 0, 0}; /* set by decode; zeroed for gcc's flow analysis */
    if (!check_type(m, vr, var_integer, &r, msg, len)
        || !check_room(m, r, n_values, *index, msg, len)) {
        return false;
    }
    if (r.block != 0 || !integer_value(m, r, &values[*index])) {
        snprintf(msg, len, "%s has no storage in this build", r.info->name);
        return false;
    }
    (*index)++;
    return true;
}

bool model_get_uint64(const ModelData *m, unsigned vr, uint64_t values[], size_t n_values,
                      size_t *index, char *msg, size_t len) {
    VarRef r = {NULL, 0, 0, 0}; /* set by decode; zeroed for gcc's flow analysis */
    if (!check_type(m, vr, var_uint64, &r, msg, len)
        || !check_room(m, r, n_values, *index, msg, len)) {
        return false;
    }
    if (r.block == 0 && r.first == vr_n) {
        values[(*index)++] = (uint64_t)m->n;
#if FMI_VERSION == 3
    } else if (r.block == 0 && r.first == vr_n_bodies) {
        values[(*index)++] = (uint64_t)m->n + 1u;
#endif
    } else {
        snprintf(msg, len, "%s has no storage in this build", r.info->name);
        return false;
    }
    return true;
}

bool model_get_boolean(const ModelData *m, unsigned vr, bool values[], size_t n_values,
                       size_t *index, char *msg, size_t len) {
    VarRef r = {NULL, 0, 0, 0}; /* set by decode; zeroed for gcc's flow analysis */
    int k;
    if (!check_type(m, vr, var_boolean, &r, msg, len)
        || !check_room(m, r, n_values, *index, msg, len)) {
        return false;
    }
    if (r.block == 0 && r.first == vr_jackknifed) {
        values[(*index)++] = m->jackknifed;
        return true;
    }
    if (r.block == blk_slipping) {
        for (k = 0; k < r.count; k++) {
            values[(*index)++] = m->slipping[r.first + k];
        }
        return true;
    }
    snprintf(msg, len, "%s has no storage in this build", r.info->name);
    return false;
}

/* ---------------------------------------------------------------- set */

/* Inputs can be set after initialization too, parameters only before its end, structural
   parameters only before it begins (and they alone in Configuration Mode); r is a known
   variable. */
static bool settable(const ModelData *m, unsigned vr, VarRef r, ModelPhase phase, char *msg,
                     size_t len) {
    char name[64];
    model_variable_name(m, vr, name, sizeof(name));
    if (phase == phase_configuration && r.info->causality != var_structural_parameter) {
        snprintf(msg, len, "%s cannot be set in Configuration Mode: only the structural "
                 "parameters (n, n_bodies) can; leave it with fmi3ExitConfigurationMode first",
                 name);
        return false;
    }
    switch (r.info->causality) {
    case var_input:
        return true;
    case var_parameter:
        if (phase >= phase_running) {
            snprintf(msg, len, "parameter %s is fixed: it can be set only in Instantiated or "
                     "Initialization Mode", name);
            return false;
        }
        return true;
    case var_structural_parameter:
        if (phase == phase_instantiated || phase == phase_configuration) {
            return true;
        }
        snprintf(msg, len, "%s is a structural parameter (now n = %d): it can be set only "
                 "before initialization, in Configuration Mode or Instantiated", name, m->n);
        return false;
    case var_independent:
        snprintf(msg, len, "%s is the independent variable: it cannot be set", name);
        return false;
    case var_output: case var_calculated_parameter: case var_local:
        break;
    }
    if (r.block == 0 && r.first == vr_n) {
        snprintf(msg, len, "n is a constant fixed by the build (n = %d); build another FMU for "
                 "another number of trailers", m->n);
    } else {
        snprintf(msg, len, "%s is an output or calculated parameter and cannot be set", name);
    }
    return false;
}

/* An input value: finite, and no imposed slide once slip_mode 1 is fixed. */
static bool check_input(const ModelData *m, VarRef r, int k, double value, ModelPhase phase,
                        char *msg, size_t len) {
    char name[64];
    if (!isfinite(value)) {
        snprintf(msg, len, "input %s = %g: must be finite",
                 element_name(r, k, name, sizeof(name)), value);
        return false;
    }
    if (r.block == blk_slide && value != 0.0 && m->slip_mode == 1 && phase >= phase_running) {
        /* slip_mode is fixed now; before, the combination is checked when initialization
           ends (model_check_combinations), whatever order the importer sets them in */
        snprintf(msg, len, "input %s = %g: an imposed slide is the kinematic disturbance of "
                 "slip_mode 0; with slip_mode = 1 push the trailer with push_x, push_y instead",
                 element_name(r, k, name, sizeof(name)), value);
        return false;
    }
    return true;
}

bool model_set_real(ModelData *m, unsigned vr, const double values[], size_t n_values,
                    size_t *index, ModelPhase phase, char *msg, size_t len) {
    VarRef r = {NULL, 0, 0, 0}; /* set by decode; zeroed for gcc's flow analysis */
    int k;
    m->outputs_valid = false; /* every set may change the outputs */
    if (!check_type(m, vr, var_real, &r, msg, len) || !settable(m, vr, r, phase, msg, len)
        || !check_room(m, r, n_values, *index, msg, len)) {
        return false;
    }
    for (k = 0; k < r.count; k++) {
        double *p = real_value(m, r, k);
        const double value = values[*index];
        if (p == NULL) {
            snprintf(msg, len, "%s has no storage in this build", r.info->name);
            return false;
        }
        if (r.info->causality == var_input) {
            if (!check_input(m, r, k, value, phase, msg, len)) {
                return false;
            }
            m->outputs_valid = false; /* outputs depend directly on the inputs */
        }
        *p = value; /* parameters are checked in model_check_parameters */
        (*index)++;
    }
    return true;
}

bool model_set_integer(ModelData *m, unsigned vr, const int values[], size_t n_values,
                       size_t *index, ModelPhase phase, char *msg, size_t len) {
    VarRef r = {NULL, 0, 0, 0}; /* set by decode; zeroed for gcc's flow analysis */
    m->outputs_valid = false; /* every set may change the outputs */
    if (!check_type(m, vr, var_integer, &r, msg, len) || !settable(m, vr, r, phase, msg, len)
        || !check_room(m, r, n_values, *index, msg, len)) {
        return false;
    }
    if (r.block == 0 && r.first == vr_slip_mode) {
        m->slip_mode = values[(*index)++]; /* checked in model_check_parameters */
        return true;
    }
    snprintf(msg, len, "%s has no storage in this build", r.info->name);
    return false;
}

/* A structural parameter's value against its range: n sizes the arrays, so it is checked now. */
static bool check_structural(VarRef r, uint64_t value, char *msg, size_t len) {
    if ((double)value >= r.info->min && (double)value <= r.info->max) {
        return true;
    }
    snprintf(msg, len, "%s = %llu: allowed %g to %g (%s)", r.info->name,
             (unsigned long long)value, r.info->min, r.info->max, r.info->reason);
    return false;
}

bool model_set_uint64(ModelData *m, unsigned vr, const uint64_t values[], size_t n_values,
                      size_t *index, ModelPhase phase, char *msg, size_t len) {
    VarRef r = {NULL, 0, 0, 0}; /* set by decode; zeroed for gcc's flow analysis */
    uint64_t value;
    m->outputs_valid = false; /* every set may change the outputs */
    if (!check_type(m, vr, var_uint64, &r, msg, len) || !settable(m, vr, r, phase, msg, len)
        || !check_room(m, r, n_values, *index, msg, len)) {
        return false;
    }
    value = values[*index];
    if (!check_structural(r, value, msg, len)) {
        return false;
    }
    if (r.block == 0 && r.first == vr_n) {
        if ((int)value != m->n) {
            model_set_trailers(m, (int)value);
        }
#if FMI_VERSION == 3
    } else if (r.block == 0 && r.first == vr_n_bodies) {
        m->n_bodies_set = (int)value; /* must be n + 1 when configuration ends */
#endif
    } else {
        snprintf(msg, len, "%s has no storage in this build", r.info->name);
        return false;
    }
    (*index)++;
    return true;
}

bool model_set_boolean(ModelData *m, unsigned vr, const bool values[], size_t n_values,
                       size_t *index, ModelPhase phase, char *msg, size_t len) {
    VarRef r = {NULL, 0, 0, 0}; /* set by decode; zeroed for gcc's flow analysis */
    (void)values;
    m->outputs_valid = false; /* every set may change the outputs */
    if (!check_type(m, vr, var_boolean, &r, msg, len) || !settable(m, vr, r, phase, msg, len)
        || !check_room(m, r, n_values, *index, msg, len)) {
        return false;
    }
    snprintf(msg, len, "%s has no storage in this build", r.info->name);
    return false;
}

bool model_check_structure(ModelData *m, char *msg, size_t len) {
    if (m->n_bodies_set != 0 && m->n_bodies_set != m->n + 1) {
        snprintf(msg, len, "n_bodies = %d: must be n + 1 = %d (n_bodies follows n: set n alone)",
                 m->n_bodies_set, m->n + 1);
        return false;
    }
    m->n_bodies_set = 0;
    return true;
}

/* ---------------------------------------------------------------- parameter checks */

/* value of parameter r (a Real or Integer scalar, or element k of a Real array) as a double;
   NaN if it has no storage */
static double parameter_value(const ModelData *m, VarRef r, int k) {
    const double *p;
    int value;
    if (r.info->type == var_integer) {
        return (r.block == 0 && integer_value(m, r, &value)) ? (double)value : NAN;
    }
    p = real_value((ModelData *)m, r, k); /* only read */
    return p != NULL ? *p : NAN;
}

static bool check_parameter(const ModelData *m, VarRef r, int k, char *msg, size_t len) {
    const VarInfo *info = r.info;
    const double value = parameter_value(m, r, k);
    char name[64];
    if (info->bounded ? (value >= info->min && value <= info->max) : isfinite(value)) {
        return true;
    }
    element_name(r, k, name, sizeof(name));
    if (info->bounded) {
        snprintf(msg, len, "%s = %g: allowed %g to %g%s%s (%s)", name, value, info->min,
                 info->max, info->unit[0] ? " " : "", info->unit, info->reason);
    } else {
        snprintf(msg, len, "%s = %g: must be finite", name, value);
    }
    return false;
}

bool model_check_parameters(const ModelData *m, char *msg, size_t len) {
    VarRef r;
    int block, k;
    for (r.first = 1; r.first < SCALAR_VR_END; r.first++) {
        r.block = 0;
        r.count = 1;
        r.info = &scalar_info[r.first];
        if (r.info->name != NULL && r.info->causality == var_parameter
            && !check_parameter(m, r, 0, msg, len)) {
            return false;
        }
    }
    for (block = 1; block < BLOCK_END; block++) {
        r.block = block;
        r.info = &block_info[block];
        if (r.info->name == NULL || r.info->causality != var_parameter) {
            continue;
        }
        r.first = r.info->first;
        r.count = m->n + r.info->last_offset - r.info->first + 1;
        for (k = 0; k < r.count; k++) {
            if (!check_parameter(m, r, k, msg, len)) {
                return false;
            }
        }
    }
    return true;
}
