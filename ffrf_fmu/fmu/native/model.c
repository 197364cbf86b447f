/* The body FMU's behaviour (the twin of ffrf_fmu/fmu/core.py `BodyCoSim`, which the pythonfmu route
 * keeps): values by value reference, parameters checked at initialization, the point values of a
 * communication step (runtime/input_rule.py), n equal internal steps in the C runtime, outputs, rollback on a
 * discard, directional derivatives of the last step (fmu/derivatives.py) and the FMU state.
 *
 * Statuses (variables.py, builder.DESCRIPTION): fmi2Discard for a numerical failure the master can
 * recover from (the FMU stays at t_c); fmi2Error for everything else, with the cause logged. The
 * messages are those of the Python FMU, word for word (tests/test_fmu_faults.py checks both). */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <limits.h>
#include <string.h>

#include "body.h"
#include "initialize.h"
#include "model.h"

static const char *const TERM_NAMES[FMU_TERM_SETS] = {"linear", "gyroscopic", "full"};

const char *const fmu_log_category[FMU_LOG_CATEGORIES] = {"logStatusWarning", "logStatusDiscard", "logStatusError",
                                                          "logStatusFatal", "logAll"};
enum { LOG_ALL = FMU_LOG_CATEGORIES - 1 };

/* the category of a message of this status: fmi2Warning .. fmi2Fatal their own, OK (and Pending) logAll */
static int log_category(fmi2Status status)
{
    return status >= fmi2Warning && status <= fmi2Fatal ? (int)status - (int)fmi2Warning : LOG_ALL;
}

unsigned model_log_categories(int logging_on)
{
    unsigned all = (1u << FMU_LOG_CATEGORIES) - 1u;
    return logging_on ? all : all & ~(1u << LOG_ALL);
}

void fmu_log(fmu_instance *m, fmi2Status status, const char *fmt, ...)
{
    int category = log_category(status);
    if ((!m->cb.logger && !m->sink) || !(m->log_categories & (1u << category)))
        return;
    char text[4 * FMU_MESSAGE];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    if (m->sink)
        m->sink(m, (int)status, fmu_log_category[category], text);
    else
        m->cb.logger(m->cb.componentEnvironment, m->name, status, fmu_log_category[category], "%s", text);
}

const char *py_repr(double x, char *buf, size_t len)
{
    if (isnan(x)) {
        snprintf(buf, len, "nan");
        return buf;
    }
    if (isinf(x)) {
        snprintf(buf, len, x > 0 ? "inf" : "-inf");
        return buf;
    }
    int p = 1;
    char tmp[64];
    for (; p < 17; p++) { /* the shortest decimal that reads back as x */
        snprintf(tmp, sizeof tmp, "%.*e", p - 1, x);
        if (strtod(tmp, NULL) == x)
            break;
    }
    snprintf(tmp, sizeof tmp, "%.*e", p - 1, x);
    int exp10 = atoi(strchr(tmp, 'e') + 1);
    if (exp10 >= -4 && exp10 < 16) { /* Python's repr: positional, with ".0" when whole */
        int decimals = p - 1 - exp10;
        snprintf(buf, len, "%.*f", decimals > 0 ? decimals : 0, x);
        if (!strchr(buf, '.'))
            strncat(buf, ".0", len - strlen(buf) - 1);
    } else {
        snprintf(buf, len, "%.*g", p, x);
    }
    return buf;
}

/* "[a, b, c]" of three doubles, as Python's list repr */
static const char *repr3(const double v[3], char *buf, size_t len)
{
    char a[32], b[32], c[32];
    snprintf(buf, len, "[%s, %s, %s]", py_repr(v[0], a, 32), py_repr(v[1], b, 32), py_repr(v[2], c, 32));
    return buf;
}

/* ------------------------------------------------------------------ set-up */

static fmi2Status model_setup(fmu_instance *m)
{
    const int n = m->desc.n_vars;
    size_t n_row = (size_t)m->desc.n_ports * FFRF_OUTPUT_WIDTH + FFRF_N_ENERGIES + 1 + 3 * (size_t)m->desc.n_probes +
                   2 * (size_t)m->desc.n_modal;
    m->values = calloc((size_t)n, sizeof(double));
    m->start_values = calloc((size_t)n, sizeof(double));
    m->initialized_with = calloc((size_t)n, sizeof(double));
    m->last_values = calloc((size_t)n, sizeof(double));
    m->deriv_values = calloc((size_t)n, sizeof(double));
    m->deriv_sides = calloc(2 * (size_t)n, sizeof(double));
    m->point_values = calloc((size_t)(m->desc.n_ports ? m->desc.n_ports : 1) * FFRF_POINT_WIDTH, sizeof(double));
    m->row = calloc(n_row, sizeof(double));
    if (!m->values || !m->start_values || !m->initialized_with || !m->last_values || !m->deriv_values ||
        !m->deriv_sides || !m->point_values || !m->row) {
        fmu_log(m, fmi2Error, "%sInstantiate: out of memory", FMU_API(m));
        return fmi2Error;
    }
    for (int i = 0; i < n; i++)
        m->start_values[i] = m->values[i] = m->desc.vars[i].start;
    m->mode = MODE_INSTANTIATED;
    m->body_terms = -1;
    return fmi2OK;
}

fmi2Status model_instantiate(fmu_instance *m, const char *call, const char *name, const char *resource_uri,
                             const char *token, const char *token_word, const char *refusal)
{
    m->mode = MODE_ERROR;
    const char *n = name ? name : "";
    m->name = malloc(strlen(n) + 1);
    if (!m->name)
        return fmi2Error;
    strcpy(m->name, n);
    if (refusal) {
        fmu_log(m, fmi2Error, "%s: %s", call, refusal);
        return fmi2Error;
    }
    char err[4200], path[4096];
    if (fmu_resource_path(resource_uri, path, sizeof path, err, sizeof err) ||
        fmu_description_load(&m->desc, path, err, sizeof err)) {
        fmu_log(m, fmi2Error, "%s: %s", call, err);
        return fmi2Error;
    }
    if (!token || strcmp(token, m->desc.guid) != 0) {
        fmu_log(m, fmi2Error, "%s: wrong %s %s: this FMU (%s) has %s", call, token_word, token ? token : "(NULL)",
                m->desc.description, m->desc.guid);
        return fmi2Error;
    }
    return model_setup(m);
}

fmu_instance *model_allowed(fmu_instance *m, const char *call, int modes)
{
    if (!m)
        return NULL;
    if (!(m->mode & modes)) {
        const char *api = FMU_API(m);
        switch (m->mode) {
        case MODE_INSTANTIATED:
            fmu_log(m, fmi2Error, "%s is not allowed when the FMU is instantiated (before %sEnterInitializationMode)",
                    call, api);
            break;
        case MODE_INITIALIZATION:
            fmu_log(m, fmi2Error, "%s is not allowed when the FMU is in initialization mode", call);
            break;
        case MODE_STEP:
            fmu_log(m, fmi2Error, "%s is not allowed when the FMU is in step mode", call);
            break;
        case MODE_TERMINATED:
            fmu_log(m, fmi2Error, "%s is not allowed when the FMU is terminated (after %sTerminate)", call, api);
            break;
        default:
            fmu_log(m, fmi2Error, "%s is not allowed when the FMU is in error (a failed instantiation or "
                    "initialization: reset or free it)", call);
        }
        return NULL;
    }
    return m;
}

fmi2Status model_refused(fmu_instance *m, const char *call, const char *why)
{
    if (m)
        fmu_log(m, fmi2Error, "%s: %s", call, why);
    return fmi2Error;
}

fmi2Status model_set_logging(fmu_instance *m, const char *call, int on, size_t n_categories,
                             const char *const categories[])
{
    if (!model_allowed(m, call, MODES_ANY))
        return fmi2Error;
    if (n_categories && !categories) {
        fmu_log(m, fmi2Error, "%s: NULL categories for nCategories = %zu", call, n_categories);
        return fmi2Error;
    }
    unsigned named = n_categories ? 0u : (1u << FMU_LOG_CATEGORIES) - 1u;
    for (size_t i = 0; i < n_categories; i++) {
        int k = 0;
        while (k < FMU_LOG_CATEGORIES && !(categories[i] && strcmp(categories[i], fmu_log_category[k]) == 0))
            k++;
        if (k == FMU_LOG_CATEGORIES) {
            char known[160] = "";
            for (int j = 0; j < FMU_LOG_CATEGORIES; j++)
                snprintf(known + strlen(known), sizeof known - strlen(known), "%s%s", j ? ", " : "", fmu_log_category[j]);
            fmu_log(m, fmi2Error, "%s: unknown log category \"%s\" (this FMU declares %s); nothing changed", call,
                    categories[i] ? categories[i] : "(NULL)", known);
            return fmi2Error;
        }
        named |= 1u << k;
    }
    m->log_categories = on ? m->log_categories | named : m->log_categories & ~named;
    return fmi2OK;
}

fmi2Status model_setup_experiment(fmu_instance *m, const char *call, double start_time, int has_stop, double stop_time)
{
    if (!model_allowed(m, call, MODE_INSTANTIATED))
        return fmi2Error;
    m->start_time = start_time;
    m->has_stop = has_stop;
    m->stop_time = stop_time;
    return fmi2OK;
}

fmi2Status model_enter_initialization(fmu_instance *m, const char *call)
{
    if (!model_allowed(m, call, MODE_INSTANTIATED))
        return fmi2Error;
    m->mode = MODE_INITIALIZATION;
    return fmi2OK;
}

fmi2Status model_terminate(fmu_instance *m, const char *call)
{
    if (!model_allowed(m, call, MODE_STEP | MODE_INITIALIZATION))
        return fmi2Error;
    m->mode = MODE_TERMINATED;
    return fmi2OK;
}

fmi2Status model_reset(fmu_instance *m, const char *call)
{
    if (!model_allowed(m, call, MODES_ANY))
        return fmi2Error;
    memcpy(m->values, m->start_values, sizeof(double) * (size_t)m->desc.n_vars);
    m->mode = MODE_INSTANTIATED;
    m->start_time = 0.0;
    m->has_stop = 0;
    m->failure[0] = m->discarded[0] = 0;
    m->initialized = 0;
    m->have_last = 0;
    return fmi2OK;
}

static void free_state_buffers(fmu_instance *m)
{
    free(m->rollback);
    free(m->end_state);
    free(m->ref_state);
    m->rollback = m->end_state = m->ref_state = NULL;
    m->state_size = 0;
}

void model_free(fmu_instance *m)
{
    if (m->body)
        ffrf_body_free(m->body);
    free_state_buffers(m);
    free(m->values);
    free(m->start_values);
    free(m->initialized_with);
    free(m->last_values);
    free(m->deriv_values);
    free(m->deriv_sides);
    free(m->point_values);
    free(m->row);
    fmu_description_free(&m->desc);
    free(m->name);
}

/* ------------------------------------------------------------------ values */

/* every value reference exists and is of the type `type` (TYPE_*): fmi2OK, or fmi2Error naming the bad ones */
static fmi2Status model_check_type(fmu_instance *m, const fmi2ValueReference vr[], size_t n, int type, const char *kind)
{
    const fmu_description *d = &m->desc;
    char list[512] = "";
    size_t k = 0, bad = 0;
    for (size_t i = 0; i < n; i++)
        if (vr[i] >= (fmi2ValueReference)d->n_vars && bad++ < 6)
            k += (size_t)snprintf(list + k, k < sizeof list ? sizeof list - k : 0, "%s%u", bad > 1 ? ", " : "", vr[i]);
    if (bad) {
        fmu_log(m, fmi2Error, "%s: unknown value reference(s) [%s%s] (this FMU has 0..%d)", kind, list,
                bad > 6 ? ", ..." : "", d->n_vars - 1);
        return fmi2Error;
    }
    static const char *const TYPES[] = {"Real", "Integer", "Boolean", "String"};
    for (size_t i = 0; i < n; i++)
        if (d->vars[vr[i]].type != type && bad++ < 6)
            k += (size_t)snprintf(list + k, k < sizeof list ? sizeof list - k : 0, "%s%u (%s: %s)", bad > 1 ? ", " : "",
                                  vr[i], d->vars[vr[i]].name, TYPES[d->vars[vr[i]].type]);
    if (bad) {
        fmu_log(m, fmi2Error, "%s: value reference(s) %s are not %s", kind, list, TYPES[type]);
        return fmi2Error;
    }
    return fmi2OK;
}

static int initialize(fmu_instance *m);
static size_t small_copy(const ffrf_body *b, double *buf);

static int inputs_changed(const fmu_instance *m)
{
    if (!m->initialized)
        return 1;
    for (int i = 0; i < m->desc.n_vars; i++) {
        if (m->desc.vars[i].causality == CAUS_OUTPUT)
            continue;
        double a = m->values[i], b = m->initialized_with[i];
        if (!(a == b || (isnan(a) && isnan(b))))
            return 1;
    }
    return 0;
}

/* outputs read in initialization mode reflect the inputs and parameters set so far */
static void refresh_initial_outputs(fmu_instance *m, const fmi2ValueReference vr[], size_t n)
{
    if (m->mode != MODE_INITIALIZATION)
        return;
    for (size_t i = 0; i < n; i++)
        if (m->desc.vars[vr[i]].causality == CAUS_OUTPUT) {
            if (inputs_changed(m))
                initialize(m);
            return;
        }
}

fmi2Status model_get_scalars(fmu_instance *m, const fmi2ValueReference vr[], size_t n, int as, void *value)
{
    refresh_initial_outputs(m, vr, n);
    for (size_t i = 0; i < n; i++) {
        double v = m->values[vr[i]];
        if (as == AS_FLOAT64)
            ((double *)value)[i] = v;
        else if (as == AS_INT)
            ((int *)value)[i] = (int)v;
        else
            ((int32_t *)value)[i] = (int32_t)v;
    }
    return fmi2OK;
}

fmi2Status model_set_scalars(fmu_instance *m, const char *call, const fmi2ValueReference vr[], size_t n, int as,
                             const void *value)
{
    for (size_t i = 0; i < n; i++) {
        const fmu_variable *v = &m->desc.vars[vr[i]];
        if (v->causality == CAUS_OUTPUT) {
            fmu_log(m, fmi2Error, "%s: %s is an output: it cannot be set", call, v->name);
            return fmi2Error;
        }
        if (v->causality == CAUS_PARAMETER && m->mode == MODE_STEP) {
            fmu_log(m, fmi2Error, "%s: %s is a fixed parameter: it cannot change after initialization", call, v->name);
            return fmi2Error;
        }
        m->values[vr[i]] = as == AS_FLOAT64 ? ((const double *)value)[i]
                           : as == AS_INT   ? (double)((const int *)value)[i]
                                            : (double)((const int32_t *)value)[i];
    }
    return fmi2OK;
}

/* the instance, when every value reference exists and is of the call's type (checked first: a bad
 * reference is named whatever the state), the call is allowed in the instance's state and the arrays are there */
static fmu_instance *checked(fmu_instance *m, const char *call, int modes, const fmi2ValueReference vr[], size_t n,
                             int type, const void *value)
{
    if (!m)
        return NULL;
    if (n && !vr) {
        fmu_log(m, fmi2Error, "%s: NULL value references for %zu values", call, n);
        return NULL;
    }
    if (model_check_type(m, vr, n, type, call) != fmi2OK || !model_allowed(m, call, modes))
        return NULL;
    if (n && !value) {
        fmu_log(m, fmi2Error, "%s: NULL array for %zu values", call, n);
        return NULL;
    }
    return m;
}

fmi2Status model_get_values(fmu_instance *m, const char *call, int type, const fmi2ValueReference vr[], size_t n,
                            void *value)
{
    if (!checked(m, call, MODES_GET, vr, n, type, value))
        return fmi2Error;
    return type == TYPE_REAL || type == TYPE_INTEGER ? model_get_scalars(m, vr, n, type == TYPE_REAL ? AS_FLOAT64 : AS_INT,
                                                                         value)
                                                     : fmi2OK; /* no variables of the other types: n is 0 */
}

fmi2Status model_set_values(fmu_instance *m, const char *call, int type, const fmi2ValueReference vr[], size_t n,
                            const void *value)
{
    if (!checked(m, call, MODES_SET, vr, n, type, value))
        return fmi2Error;
    return type == TYPE_REAL || type == TYPE_INTEGER
               ? model_set_scalars(m, call, vr, n, type == TYPE_REAL ? AS_FLOAT64 : AS_INT, value)
               : fmi2OK;
}

/* ------------------------------------------------------------------ parameters and inputs */

static int terms_of(const fmu_instance *m)
{
    return (int)m->values[m->desc.vr_terms];
}

/* why the parameters cannot start a run ('' when they can): parameters.py `_check_parameters` */
static int check_parameters(fmu_instance *m, char *why, size_t len)
{
    const fmu_description *d = &m->desc;
    const double *v = m->values;
    char a[48], b[160];
    double step = v[d->vr_step], rho = v[d->vr_rho_inf], terms = v[d->vr_terms];
    if (!(step > 0.0 && isfinite(step))) {
        snprintf(why, len, "parameter solver.step must be positive and finite, got %s", py_repr(step, a, sizeof a));
        return 1;
    }
    if (m->has_stop) {
        double span = m->stop_time - m->start_time;
        if (span > 0.0 && step > span) {
            snprintf(why, len, "parameter solver.step = %g s is longer than the experiment (%g s to %g s)", step,
                     m->start_time, m->stop_time);
            return 1;
        }
    }
    if (!(rho >= 0.0 && rho <= 1.0)) {
        snprintf(why, len, "parameter solver.rho_inf must be in [0, 1], got %s", py_repr(rho, a, sizeof a));
        return 1;
    }
    if (!(terms == 0.0 || terms == 1.0 || terms == 2.0)) {
        snprintf(why, len, "parameter solver.terms must be 0 (linear), 1 (gyroscopic) or 2 (full), got %s",
                 py_repr(terms, a, sizeof a));
        return 1;
    }
    double cap = v[d->vr_max_iterations];
    if (!(cap >= 0.0 && cap <= (double)INT_MAX && cap == floor(cap))) { /* the runtime's cap is an int */
        snprintf(why, len, "parameter solver.max_newton_iterations must be an integer in 0 .. 2^31 - 1 (0: no cap), got %s",
                 py_repr(cap, a, sizeof a));
        return 1;
    }
    if (!d->image[(int)terms]) {
        if ((int)terms == 2)
            snprintf(why, len, "parameter solver.terms = 2 (full) needs the inertia data W1, W2, which this FMU was "
                     "built without: build it from a scene with terms = \"full\"");
        else
            snprintf(why, len, "parameter solver.terms = %d (%s): this FMU was built without that term set",
                     (int)terms, TERM_NAMES[(int)terms]);
        return 1;
    }
    static const char *const names[3] = {"gravity", "initial.v", "initial.w"};
    const int *vrs[3] = {d->vr_gravity, d->vr_velocity, d->vr_angular_velocity};
    double vec[3][3];
    for (int k = 0; k < 3; k++)
        for (int i = 0; i < 3; i++)
            vec[k][i] = v[vrs[k][i]];
    for (int k = 0; k < 3; k++)
        if (!(isfinite(vec[k][0]) && isfinite(vec[k][1]) && isfinite(vec[k][2]))) {
            snprintf(why, len, "parameter %s is not finite: %s", names[k], repr3(vec[k], b, sizeof b));
            return 1;
        }
    for (int p = 0; p < d->n_ports; p++) {
        const int32_t *dv = d->disp_vr + 3 * p;
        if (dv[0] < 0)
            continue;
        double u[3] = {v[dv[0]], v[dv[1]], v[dv[2]]};
        if (!(isfinite(u[0]) && isfinite(u[1]) && isfinite(u[2]))) {
            snprintf(why, len, "parameter initial.%s.d is not finite: %s", d->ports[p].name, repr3(u, b, sizeof b));
            return 1;
        }
    }
    for (int k = 1; k < 3; k++) { /* initial velocities on a motion-driven part: its input gives them */
        const int translation = k == 1;
        if (vec[k][0] == 0.0 && vec[k][1] == 0.0 && vec[k][2] == 0.0)
            continue;
        for (int p = 0; p < d->n_ports; p++)
            if ((translation ? d->ports[p].translation : d->ports[p].rotation) == PART_MOTION) {
                snprintf(why, len, "parameter %s = %s is set, but the %s of port %s is motion-driven: its input %s.%s "
                         "gives the initial rigid %s (set that input instead)", names[k], repr3(vec[k], b, sizeof b),
                         translation ? "translation" : "rotation", d->ports[p].name, d->ports[p].name,
                         translation ? "v" : "w", translation ? "velocity" : "angular velocity");
                return 1;
            }
    }
    {   /* structural damping: ratios and Rayleigh coefficients finite and >= 0 (!(x >= 0) also catches NaN) */
        int vr = -1;
        for (int i = -2; i < d->n_damp_ratios && vr < 0; i++) {
            int k = i == -2 ? d->vr_damp_alpha : i == -1 ? d->vr_damp_beta : d->damp_ratio_vr[i];
            if (!(v[k] >= 0.0 && isfinite(v[k])))
                vr = k;
        }
        if (vr >= 0) {
            snprintf(why, len, "parameter %s must be finite and >= 0 (a damping ratio or Rayleigh coefficient), got %s",
                     d->vars[vr].name, py_repr(v[vr], a, sizeof a));
            return 1;
        }
    }
    for (int p = 0; p < d->n_ports; p++) {
        const int32_t *cv = d->coupling_vr + 12 * p;
        int bad = 0, any = 0;
        for (int i = 0; i < 12; i++)
            if (cv[i] >= 0) {
                any = 1;
                bad |= !(isfinite(v[cv[i]]) && v[cv[i]] >= 0.0);
            }
        if (any && bad) {
            size_t k = (size_t)snprintf(why, len, "parameters %s.coupling.* must be finite and >= 0, got [",
                                        d->ports[p].name);
            for (int i = 0; i < 12 && k < len; i++)
                k += (size_t)snprintf(why + k, len - k, "%s%s", i ? ", " : "",
                                      py_repr(cv[i] >= 0 ? v[cv[i]] : 0.0, a, sizeof a));
            if (k < len)
                snprintf(why + k, len - k, "]");
            return 1;
        }
    }
    return 0;
}

/* The point values (runtime/input_rule.py) of the inputs in `values` at t_c (signals.py `_point_values`): one row per port, the
 * columns of runtime/input_rule.py; checked finite, R a rotation (re-orthonormalized when not exact).
 * strict = 0 projects any R with det > 0 onto the nearest rotation (the derivatives' perturbed inputs). */
static int point_values(fmu_instance *m, const double *values, double t_c, int strict, double *out, char *why,
                        size_t len)
{
    const fmu_description *d = &m->desc;
    const int P = d->n_ports;
    for (int k = 0; k < P * FFRF_POINT_WIDTH; k++) {
        int32_t vr = d->point_vr[k];
        out[k] = vr >= 0 ? values[vr] : 0.0;
    }
    int bad = 0;
    size_t k = 0;
    char list[600] = "";
    for (int i = 0; i < d->n_vars; i++)
        if (d->vars[i].causality == CAUS_INPUT && !isfinite(values[i])) {
            if (bad < 6)
                k += (size_t)snprintf(list + k, k < sizeof list ? sizeof list - k : 0, "%s%s", bad ? ", " : "",
                                      d->vars[i].name);
            bad++;
        }
    if (bad) {
        if (bad > 6)
            snprintf(why, len, "t = %.6g s: input(s) %s and %d more not finite (NaN or inf)", t_c, list, bad - 6);
        else
            snprintf(why, len, "t = %.6g s: input(s) %s not finite (NaN or inf)", t_c, list);
        return 1;
    }
    for (int p = 0; p < P; p++) {
        if (d->ports[p].rotation == PART_FORCE)
            continue;
        double *R = out + p * FFRF_POINT_WIDTH + 9; /* row-major */
        double a = R[0], b = R[1], c = R[2], dd = R[3], e = R[4], f = R[5], g = R[6], h = R[7], i = R[8];
        double dev = fmax(fmax(fmax(fabs(a * a + dd * dd + g * g - 1.0), fabs(b * b + e * e + h * h - 1.0)),
                               fmax(fabs(c * c + f * f + i * i - 1.0), fabs(a * b + dd * e + g * h))),
                          fmax(fabs(a * c + dd * f + g * i), fabs(b * c + e * f + h * i)));
        double det = a * (e * i - f * h) - b * (dd * i - f * g) + c * (dd * h - e * g);
        if (dev > 1e-6 && strict) { /* runtime/rotation.py ROTATION_TOL */
            snprintf(why, len, "t = %.6g s: input %s.R is not a rotation matrix (not orthonormal: max |R^T R - I| = "
                     "%.3g > %g)", t_c, d->ports[p].name, dev, 1e-6);
            return 1;
        }
        if (det <= 0.0) {
            snprintf(why, len, "t = %.6g s: input %s.R is not a rotation matrix (a reflection: det = %.6g, a rotation "
                     "has det = +1)", t_c, d->ports[p].name, det);
            return 1;
        }
        if (dev > 1e-12) { /* the nearest rotation, the polar factor: Newton's iteration X <- (X + X^-T) / 2 */
            for (int it = 0; it < 100; it++) {
                double inv[9], change = 0.0;
                ffrf_inv3(R, inv);
                for (int r = 0; r < 3; r++)
                    for (int s = 0; s < 3; s++) {
                        double x = 0.5 * (R[3 * r + s] + inv[3 * s + r]);
                        change = fmax(change, fabs(x - R[3 * r + s]));
                        R[3 * r + s] = x;
                    }
                if (change < 1e-15)
                    break;
            }
        }
    }
    return 0;
}

/* ------------------------------------------------------------------ initialization */

static void alpha_coefficients(double rho, double *am, double *af, double *gamma)
{
    *am = (3.0 - rho) / (2.0 * (1.0 + rho));
    *af = 1.0 / (1.0 + rho);
    *gamma = 0.5 + *am - *af;
}

/* The body of the term set asked for, with the parameters of this run (parameters.py `_make_system`). */
static int make_body(fmu_instance *m, char *why, size_t len)
{
    const fmu_description *d = &m->desc;
    int terms = terms_of(m);
    if (!m->body || m->body_terms != terms) {
        char err[512];
        ffrf_body *b = ffrf_body_create(d->image[terms], d->image_size[terms], err, sizeof err);
        if (!b) {
            snprintf(why, len, "the body of term set %s cannot be created: %s", TERM_NAMES[terms], err);
            return 1;
        }
        size_t size = ffrf_body_state_size(b);
        double *r = malloc(sizeof(double) * size), *e = malloc(sizeof(double) * size),
               *ref = malloc(sizeof(double) * size);
        if (!r || !e || !ref) {
            free(r);
            free(e);
            free(ref);
            ffrf_body_free(b);
            snprintf(why, len, "out of memory");
            return 1;
        }
        if (m->body)
            ffrf_body_free(m->body);
        free_state_buffers(m);
        m->body = b;
        m->body_terms = terms;
        m->state_size = size;
        m->rollback = r;
        m->end_state = e;
        m->ref_state = ref;
        ffrf_body_get_state(b, ref);
        /* small_copy writes get_state's first doubles (checked here on the fresh body), else whole copies */
        size_t nf = (size_t)b->dims.nf, k = small_copy(b, e);
        m->small_size = (k == size - nf * nf - nf && memcmp(e, ref, sizeof(double) * k) == 0) ? k : 0;
        m->rollback_lu_valid = 0;
    }
    ffrf_body *b = m->body;
    b->rho_inf = m->values[d->vr_rho_inf];
    b->iteration_cap = (int)m->values[d->vr_max_iterations];
    alpha_coefficients(b->rho_inf, &b->am, &b->af, &b->gamma);
    double *gravity = (double *)b->data.gravity; /* the body's own copy of its image */
    for (int i = 0; i < 3; i++)
        gravity[i] = m->values[d->vr_gravity[i]];
    for (int p = 0, s = 0; p < d->n_ports; p++) { /* compliant ports: the coupling parameters */
        const int32_t *cv = d->coupling_vr + 12 * p;
        if (d->ports[p].translation != PART_COMPLIANT && d->ports[p].rotation != PART_COMPLIANT)
            continue;
        for (int i = 0; i < 12; i++)
            b->springs.KC[12 * s + i] = cv[i] >= 0 ? m->values[cv[i]] : 0.0;
        s++;
    }
    /* structural damping: the parameters into the body's ratios and coefficients, D rebuilt from the image's
     * modes (runtime/damping.py); one ratio parameter holds for every mode */
    const int ne = b->dims.n_el;
    if (d->n_damp_ratios != 1 && d->n_damp_ratios != ne) {
        snprintf(why, len, "%d damping.ratio parameters for a body of %d modes per superelement", d->n_damp_ratios, ne);
        return 1;
    }
    for (int i = 0; i < ne; i++)
        b->damping.zeta[i] = m->values[d->damp_ratio_vr[d->n_damp_ratios == 1 ? 0 : i]];
    b->damping.ab[0] = m->values[d->vr_damp_alpha];
    b->damping.ab[1] = m->values[d->vr_damp_beta];
    if (ffrf_damping_update(b)) {
        snprintf(why, len, "the damping parameters cannot be applied: negative or not finite, or this body has no "
                 "modes to damp (its image carries none)");
        return 1;
    }
    return 0;
}

static void write_outputs(fmu_instance *m, int iterations);

/* The body just initialized at the inputs of t0 put in the start state made at build, after the checks that it
 * holds for these parameters (runtime/start.py `parameter_mismatch`, the same messages) and inputs
 * (initialize.c `fmu_start_body`); 0, or 1 with why set. */
#define START_GRAVITY_TOL 1e-12 /* runtime/start.py GRAVITY_TOL (tests/test_facts.py) */
static int start_state(fmu_instance *m, const char *const *names, char *why, size_t len)
{
    static const char *const STATES[3] = {"rest", "static", "steady_spin"}; /* model.py INITIAL_STATES (tests/test_facts.py) */
    const fmu_description *d = &m->desc;
    int terms = terms_of(m);
    const double *start = d->start[terms];
    const char *state = STATES[(int)start[0]];
    double gmax = 1.0;
    for (int i = 0; i < 3; i++)
        gmax = fmax(gmax, fabs(start[1 + i]));
    for (int i = 0; i < 3; i++)
        if (fabs(m->values[d->vr_gravity[i]] - start[1 + i]) > START_GRAVITY_TOL * gmax) {
            char a[3][32], b[3][32];
            for (int k = 0; k < 3; k++) {
                py_repr(m->values[d->vr_gravity[k]], a[k], sizeof a[k]);
                py_repr(start[1 + k], b[k], sizeof b[k]);
            }
            snprintf(why, len, "parameter gravity = [%s, %s, %s] is not the [%s, %s, %s] the start state (%s, made at "
                     "build) is the equilibrium of: build the FMU for this gravity", a[0], a[1], a[2], b[0], b[1], b[2],
                     state);
            return 1;
        }
    for (int i = 0; i < 3; i++)
        if (m->values[d->vr_velocity[i]] != 0.0 || m->values[d->vr_angular_velocity[i]] != 0.0) {
            snprintf(why, len, "parameter %s is set, but the FMU starts in the start state (%s), which sets the "
                     "body's motion", m->values[d->vr_velocity[i]] != 0.0 ? "initial_velocity" : "initial_angular_velocity",
                     state);
            return 1;
        }
    for (int p = 0; p < d->n_ports; p++)
        for (int i = 0; i < 3; i++) {
            int32_t vr = d->disp_vr[3 * p + i];
            if (vr >= 0 && m->values[vr] != 0.0) {
                snprintf(why, len, "parameter initial.%s.d is set, but the FMU starts in the start state (%s), which "
                         "sets the body's motion", d->ports[p].name, state);
                return 1;
            }
        }
    return fmu_start_body(m->body, m->start_time, start + 4, d->start_count[terms] - 4, names, why, len) ? 1 : 0;
}

/* a consistent initial state from the current inputs and parameters; 0, or 1 with m->failure set */
static int initialize(fmu_instance *m)
{
    const fmu_description *d = &m->desc;
    char why[FMU_MESSAGE - 64];
    m->failure[0] = 0;
    m->have_last = 0;
    if (check_parameters(m, why, sizeof why) || point_values(m, m->values, m->start_time, 1, m->point_values, why, sizeof why)) {
        snprintf(m->failure, sizeof m->failure, "initialization: %s", why);
        return 1;
    }
    if (make_body(m, why, sizeof why)) {
        snprintf(m->failure, sizeof m->failure, "initialization failed at t = %.6g s: %s", m->start_time, why);
        return 1;
    }
    /* the cap bounds the communication steps only, as on the numpy path (its micro-step and static starts are
     * not committed steps: integrator `_step` commit_config): off until the initial state stands */
    const int cap = m->body->iteration_cap;
    m->body->iteration_cap = 0;
    double v0[3], w0[3], *disp = m->deriv_values; /* work: [n_ports][3] displacements */
    int displaced = 0;
    for (int i = 0; i < 3; i++) {
        v0[i] = m->values[d->vr_velocity[i]];
        w0[i] = m->values[d->vr_angular_velocity[i]];
    }
    /* every port with a displacement parameter (force-driven translation) takes part in the relaxation,
     * displaced or not, as in core.py (`port_displacements` holds them all) */
    const char *names[64];
    for (int p = 0; p < d->n_ports; p++) {
        names[p < 64 ? p : 63] = d->ports[p].name;
        for (int i = 0; i < 3; i++) {
            int32_t vr = d->disp_vr[3 * p + i];
            disp[3 * p + i] = vr >= 0 ? m->values[vr] : 0.0;
            displaced |= vr >= 0;
        }
    }
    ffrf_body_set_state(m->body, m->ref_state, m->state_size);
    memcpy(m->body->point_values, m->point_values, sizeof(double) * (size_t)d->n_ports * FFRF_POINT_WIDTH);
    if (fmu_initialize_body(m->body, m->start_time, v0, w0, d->origin, displaced ? disp : NULL, names, why,
                            sizeof why)) {
        snprintf(m->failure, sizeof m->failure, "initialization failed at t = %.6g s: %s", m->start_time, why);
        return 1;
    }
    if (d->start[terms_of(m)] && start_state(m, names, why, sizeof why)) {
        snprintf(m->failure, sizeof m->failure, "initialization failed at t = %.6g s: %s", m->start_time, why);
        return 1;
    }
    m->body->iteration_cap = cap;
    ffrf_body_record(m->body, m->row);
    write_outputs(m, 0);
    memcpy(m->initialized_with, m->values, sizeof(double) * (size_t)d->n_vars);
    m->initialized = 1;
    return 0;
}

fmi2Status model_exit_initialization(fmu_instance *m, const char *call)
{
    if (!model_allowed(m, call, MODE_INITIALIZATION))
        return fmi2Error;
    int failed = (inputs_changed(m) || m->failure[0]) ? initialize(m) : 0;
    m->mode = MODE_STEP;
    m->discarded[0] = 0;
    m->have_last = 0;
    if (failed) {
        fmu_log(m, fmi2Error, "%s (%sError; every doStep will return %sError until the parameters are fixed and "
                "the FMU is reset)", m->failure, FMU_API(m), FMU_API(m));
        return fmi2Error;
    }
    return fmi2OK;
}

/* ------------------------------------------------------------------ stepping */

/* The state of ffrf_body_get_state without the iteration matrix's factors, written in place over the
 * first part of a whole state (t, iterations, energy, the state arrays, the factorization's 12 meta
 * values; the factors luT and pivots follow). The factors are most of the state (226 KB of 235 KB for
 * B1 4 SE x 6 modes) and change only when a step refreshes the matrix (its version changes): a doStep
 * copies them only then, and the saved start stays the whole state, exactly (rollback, derivatives).
 * Returns the doubles written; make_body checks that they are get_state's first ones. */
static size_t small_copy(const ffrf_body *b, double *buf)
{
    const ffrf_dims *d = &b->dims;
    const ffrf_state *st = &b->state;
    const double *arrays[] = {st->xN, st->RN, st->x0, st->R0, st->eta, st->v, st->yd, st->yd_prev, st->yd_prev2,
                              st->a, st->fN, st->tN, b->lu.meta};
    const size_t sizes[] = {3 * (size_t)d->N, 9 * (size_t)d->N, 3 * (size_t)d->E, 9 * (size_t)d->E,
                            (size_t)d->E * d->nm, (size_t)d->E * d->nv, (size_t)d->ny, (size_t)d->ny, (size_t)d->ny,
                            (size_t)d->ny, 3 * (size_t)d->N, 3 * (size_t)d->N, 12};
    buf[0] = st->t;
    buf[1] = st->iterations;
    buf[2] = st->energy[0];
    buf[3] = st->energy[1];
    size_t k = 4;
    for (size_t i = 0; i < sizeof sizes / sizeof sizes[0]; i++) {
        memcpy(buf + k, arrays[i], sizeof(double) * sizes[i]);
        k += sizes[i];
    }
    return k;
}

/* the body's whole state at a step's start into m->rollback: the factors copied only when they changed */
static void save_start(fmu_instance *m)
{
    ffrf_body *b = m->body;
    if (m->small_size && m->rollback_lu_valid && b->lu.version == m->rollback_lu_version) {
        small_copy(b, m->rollback);
        return;
    }
    ffrf_body_get_state(b, m->rollback);
    m->rollback_lu_version = b->lu.version;
    m->rollback_lu_valid = 1;
}

/* the outputs of m->row (the body's output row, iterations last), the probes (eq. 92):
 * d = R_f^T (r_s - r_f) - (X_s - X_f), then every superelement's modal coordinates eta and their rates (the
 * eta slots of the rates yd, cfg_map columns 6 .. 6 + nm; resource.py output_map) */
static void outputs_into(fmu_instance *m, int iterations, double *values)
{
    const fmu_description *d = &m->desc;
    double *row = m->row;
    size_t base = (size_t)d->n_ports * FFRF_OUTPUT_WIDTH + FFRF_N_ENERGIES + 1;
    row[base - 1] = iterations; /* the most of the communication step's internal steps */
    for (int k = 0; k < d->n_probes; k++) {
        const double *s = row + FFRF_OUTPUT_WIDTH * d->probe_seen[k], *f = row + FFRF_OUTPUT_WIDTH * d->probe_frame[k];
        for (int i = 0; i < 3; i++) {
            double acc = 0.0;
            for (int j = 0; j < 3; j++)
                acc += f[3 + 3 * j + i] * (s[j] - f[j]);
            row[base + 3 * k + i] = acc - d->probe_dX[3 * k + i];
        }
    }
    const ffrf_body *b = m->body;
    if (b && d->n_modal == b->dims.E * b->dims.nm) { /* (every image of an FMU is of the same body) */
        double *eta = row + base + 3 * (size_t)d->n_probes, *rate = eta + d->n_modal;
        for (int e = 0; e < b->dims.E; e++)
            for (int i = 0; i < b->dims.nm; i++) {
                eta[e * b->dims.nm + i] = b->state.eta[e * b->dims.nm + i];
                rate[e * b->dims.nm + i] = b->state.yd[b->data.cfg_map[(size_t)e * b->dims.nc + 6 + i]];
            }
    }
    for (int i = 0; i < d->n_out; i++)
        values[d->out_vr[i]] = row[d->out_src[i]];
}

static void write_outputs(fmu_instance *m, int iterations)
{
    outputs_into(m, iterations, m->values);
}

/* n internal steps of H / n from the body's state with the point values in m->point_values; the output row into
 * m->row. 0, or 1 with the failure in why (the body then is at its last completed step); 2 when the failure is the
 * iteration cap (solver.max_newton_iterations: a real-time bound broken, an Error, not a step to retry smaller). */
static int run_step(fmu_instance *m, double t_c, double H, int n, int *worst, char *why, size_t len)
{
    ffrf_body *b = m->body;
    double hh = H / n, t0 = b->state.t;
    int status = FFRF_OK;
    memcpy(b->point_values, m->point_values, sizeof(double) * (size_t)m->desc.n_ports * FFRF_POINT_WIDTH);
    int done = ffrf_body_advance(b, FFRF_EXTRAPOLATED, n, hh, t_c, m->row, NULL, &status, worst);
    if (status != FFRF_OK || done != n) {
        if (status == FFRF_NOT_CONVERGED)
            snprintf(why, len, "t = %.6g s: Newton did not converge in %d iterations", t0 + (done + 1) * hh, b->max_iter);
        else if (status == FFRF_ITERATION_CAP) /* runtime/ports.py IterationCapReached */
            snprintf(why, len, "t = %.6g s: Newton did not converge within max_newton_iterations = %d iterations (the "
                     "cap of a step's iterations: a step that needs more fails)", t0 + (done + 1) * hh, b->iteration_cap);
        else
            snprintf(why, len, "t = %.6g s: %s", t0 + (done + 1) * hh, ffrf_status_text(status));
        return status == FFRF_ITERATION_CAP ? 2 : 1;
    }
    return 0;
}

static int finite_outputs(const fmu_instance *m)
{
    const ffrf_body *b = m->body;
    size_t n_row = (size_t)m->desc.n_ports * FFRF_OUTPUT_WIDTH + FFRF_N_ENERGIES;
    double s = 0.0;
    for (size_t i = 0; i < n_row; i++)
        s += m->row[i];
    for (int i = 0; i < b->dims.ny; i++)
        s += b->state.yd[i];
    if (isfinite(s))
        return 1;
    for (size_t i = 0; i < n_row; i++) /* a sum that overflowed on finite entries */
        if (!isfinite(m->row[i]))
            return 0;
    for (int i = 0; i < b->dims.ny; i++)
        if (!isfinite(b->state.yd[i]))
            return 0;
    return 1;
}

fmi2Status model_do_step(fmu_instance *m, const char *call, double t_c, double H)
{
    if (m && m->mode == MODE_TERMINATED) {
        fmu_log(m, fmi2Error, "t = %.6g s: %sDoStep after %sTerminate (reset or free the instance)", t_c, FMU_API(m),
                FMU_API(m));
        return fmi2Error;
    }
    if (!model_allowed(m, call, MODE_STEP))
        return fmi2Error;
    m->have_last = 0;
    if (m->failure[0]) {
        fmu_log(m, fmi2Error, "%s (doStep needs a successful initialization)", m->failure);
        return fmi2Error;
    }
    if (!m->body) {
        fmu_log(m, fmi2Error, "t = %.6g s: doStep before the end of initialization", t_c);
        return fmi2Error;
    }
    ffrf_body *b = m->body;
    double h = m->values[m->desc.vr_step], t_end = t_c + H;
    double tol = 1e-9 * fmax(1.0, fabs(t_c)) + 1e-6 * h;
    char a[48];
    if (!(H > 0.0 && isfinite(H))) {
        fmu_log(m, fmi2Error, "t = %.6g s: communication step must be positive and finite, got %s", t_c,
                py_repr(H, a, sizeof a));
        return fmi2Error;
    }
    if (!(fabs(t_c - b->state.t) <= tol)) {
        char where[FMU_MESSAGE + 200];
        if (m->discarded[0])
            snprintf(where, sizeof where, "the step from t = %.9g s was discarded (%s) and the FMU stayed there",
                     b->state.t, m->discarded);
        else
            snprintf(where, sizeof where, "the FMU is at t = %.9g s", b->state.t);
        fmu_log(m, fmi2Error, "t = %.6g s: %s; doStep must start where the last successful step ended (retry from "
                "t = %.9g s, or restore a saved FMU state first)", t_c, where, b->state.t);
        return fmi2Error;
    }
    char why[FMU_MESSAGE - 1];
    if (point_values(m, m->values, t_c, 1, m->point_values, why, sizeof why)) {
        snprintf(m->discarded, sizeof m->discarded, "%s", why);
        fmu_log(m, fmi2Discard, "%s", why);
        return fmi2Discard;
    }
    /* n equal internal steps of at most solver.step (variables.INTERNAL_STEPS; runtime/steps.py whole_steps, its
     * tolerance 1e-6): never a sliver */
    double ratio = H / h, near = nearbyint(ratio);
    int n = fabs(ratio - near) < 1e-6 * fmax(1.0, ratio) ? (near < 1.0 ? 1 : (int)near) : (int)ceil(ratio);
    save_start(m);
    int worst = 0;
    int failed = run_step(m, t_c, H, n, &worst, why, sizeof why);
    if (!failed && !finite_outputs(m)) {
        snprintf(why, sizeof why, "t = %.6g s: the state is not finite (NaN or overflow)", t_end);
        failed = 1;
    }
    if (failed) {
        ffrf_body_set_state(b, m->rollback, m->state_size);
        m->rollback_lu_valid = 0; /* set_state made a new matrix version */
        if (failed == 2) {
            fmu_log(m, fmi2Error, "%s", why);
            return fmi2Error;
        }
        snprintf(m->discarded, sizeof m->discarded, "%s", why);
        fmu_log(m, fmi2Discard, "%s", why);
        return fmi2Discard;
    }
    b->state.t = t_end; /* the master's clock, not the sum of n rounded steps */
    /* the step's start for the directional derivatives: its state (m->rollback, kept until the next doStep)
     * and its values */
    memcpy(m->last_values, m->values, sizeof(double) * (size_t)m->desc.n_vars);
    m->last_tc = t_c;
    m->last_H = H;
    m->last_n = n;
    m->have_last = 1;
    m->discarded[0] = 0;
    write_outputs(m, worst);
    return fmi2OK;
}

/* ------------------------------------------------------------------ directional derivatives */

/* derivatives.py DERIVATIVE_STEPS: relative central-difference steps of loads and of motions */
static const double STEP_LOAD = 1e-2, STEP_MOTION = 1e-5;

fmi2Status model_directional_derivative(fmu_instance *m, int meaning, const fmi2ValueReference unknown[],
                                        size_t n_unknown, const fmi2ValueReference known[], size_t n_known,
                                        const fmi2Real seed[], fmi2Real out[])
{
    const fmu_description *d = &m->desc;
    const int nv = d->n_vars;
    if (m->mode != MODE_STEP) { /* the wrappers let initialization mode through to say this */
        fmu_log(m, fmi2Error, "%s in initialization mode: the partial derivatives of the initial unknowns are not "
                "provided; in step mode it gives %s", meaning == DERIV_FMI ? "directional derivative" : "step derivative",
                meaning == DERIV_FMI ? "FMI's partial derivatives at the communication point (zero: no output depends "
                                       "directly on an input)" : "the derivatives of the last communication step");
        return fmi2Error;
    }
    for (size_t i = 0; i < n_known; i++)
        if (known[i] >= (fmi2ValueReference)nv || d->vars[known[i]].causality != CAUS_INPUT) {
            char name[64];
            snprintf(name, sizeof name, "value reference %u", known[i]);
            fmu_log(m, fmi2Error, "directional derivative: %s not input(s): the derivatives are those of outputs with "
                    "respect to inputs", known[i] < (fmi2ValueReference)nv ? d->vars[known[i]].name : name);
            return fmi2Error;
        }
    for (size_t i = 0; i < n_unknown; i++)
        if (unknown[i] >= (fmi2ValueReference)nv || d->vars[unknown[i]].causality != CAUS_OUTPUT ||
            d->vars[unknown[i]].type != TYPE_REAL) {
            if (unknown[i] >= (fmi2ValueReference)nv)
                fmu_log(m, fmi2Error, "directional derivative: value reference %u not Real output(s)", unknown[i]);
            else
                fmu_log(m, fmi2Error, "directional derivative: %s not Real output(s)", d->vars[unknown[i]].name);
            return fmi2Error;
        }
    int any = 0;
    for (size_t i = 0; i < n_known; i++) {
        if (!isfinite(seed[i])) {
            fmu_log(m, fmi2Error, "directional derivative: the seed vector is not finite");
            return fmi2Error;
        }
        any |= seed[i] != 0.0;
    }
    if (meaning == DERIV_FMI) { /* every output is a value at the end of the last step: no direct feedthrough */
        for (size_t i = 0; i < n_unknown; i++)
            out[i] = 0.0;
        return fmi2OK;
    }
    if (!m->have_last || !m->body) {
        fmu_log(m, fmi2Error, "step derivative: no communication step to differentiate (they are the "
                "derivatives of the last successful doStep; none since initialization, a failed doStep or "
                "%s)", m->fmi ? "fmi3SetFMUState" : "fmi2SetFMUstate");
        return fmi2Error;
    }
    for (size_t i = 0; i < n_unknown; i++)
        out[i] = 0.0;
    if (!any)
        return fmi2OK;
    ffrf_body *b = m->body;
    const double H = m->last_H;
    ffrf_body_get_state(b, m->end_state);
    fmi2Status status = fmi2OK;
    for (int part = 0; part < 2 && status == fmi2OK; part++) { /* loads, then motions: each with its own step */
        double size = 1.0, top = 0.0;
        int used = 0;
        for (size_t i = 0; i < n_known; i++) {
            const fmu_variable *v = &d->vars[known[i]];
            if ((v->dkind == DKIND_LOAD) != (part == 0))
                continue;
            double w = v->dkind == DKIND_RATE ? H : v->dkind == DKIND_ACCEL ? 0.5 * H * H : 1.0;
            size = fmax(size, fabs(m->last_values[known[i]] * w));
            top = fmax(top, fabs(seed[i] * w));
            used |= seed[i] != 0.0;
        }
        if (!used)
            continue;
        double eps = (part == 0 ? STEP_LOAD : STEP_MOTION) * size / top;
        for (int side = 0; side < 2 && status == fmi2OK; side++) {
            double step = side == 0 ? eps : -eps;
            double *values = m->deriv_values;
            memcpy(values, m->last_values, sizeof(double) * (size_t)nv);
            for (size_t i = 0; i < n_known; i++)
                if ((d->vars[known[i]].dkind == DKIND_LOAD) == (part == 0))
                    values[known[i]] += step * seed[i];
            char why[FMU_MESSAGE - 1];
            int worst = 0;
            if (point_values(m, values, m->last_tc, 0, m->point_values, why, sizeof why)) {
                fmu_log(m, fmi2Error, "directional derivative: %s", why);
                status = fmi2Error;
                break;
            }
            ffrf_body_set_state(b, m->rollback, m->state_size);
            if (run_step(m, m->last_tc, H, m->last_n, &worst, why, sizeof why)) {
                fmu_log(m, fmi2Error, "directional derivative of the step from t = %.6g s failed at %s", m->last_tc,
                        why + 4);
                status = fmi2Error;
                break;
            }
            double *sides = m->deriv_sides + (size_t)side * (size_t)nv;
            outputs_into(m, 0, sides);
        }
        if (status == fmi2OK)
            for (size_t i = 0; i < n_unknown; i++)
                out[i] += (m->deriv_sides[unknown[i]] - m->deriv_sides[(size_t)nv + unknown[i]]) / (2.0 * eps);
    }
    ffrf_body_set_state(b, m->end_state, m->state_size);
    m->rollback_lu_valid = 0; /* set_state made a new matrix version */
    ffrf_body_record(b, m->row); /* the row of the end of the step again (the outputs never changed) */
    return status;
}

/* v^T J: one directional derivative per known element j (the column J e_j, the seed e_j over all the knowns),
 * then its product with the seed v. The columns are those the directional call of the same meaning gives for
 * the same knowns and the unit seeds, to the bit (a step derivative's column costs two re-runs of the last
 * step: docs/fmu.md). */
fmi2Status model_adjoint_derivative(fmu_instance *m, const char *call, int meaning, const fmi2ValueReference unknown[],
                                    size_t n_unknown, const fmi2ValueReference known[], size_t n_known,
                                    const fmi2Real seed[], fmi2Real out[])
{
    double *column = malloc(sizeof(double) * (n_unknown ? n_unknown : 1));
    double *unit = calloc(n_known ? n_known : 1, sizeof(double));
    fmi2Status s = fmi2OK;
    if (!column || !unit) {
        fmu_log(m, fmi2Error, "%s: out of memory", call);
        s = fmi2Error;
    }
    for (size_t j = 0; j < n_known && s == fmi2OK; j++) { /* J e_j over all the knowns, as the directional call */
        unit[j] = 1.0;
        s = model_directional_derivative(m, meaning, unknown, n_unknown, known, n_known, unit, column);
        unit[j] = 0.0;
        double sum = 0.0;
        for (size_t i = 0; i < n_unknown; i++)
            sum += seed[i] * column[i];
        out[j] = sum;
    }
    free(unit);
    free(column);
    return s;
}

/* ------------------------------------------------------------------ FMU state */

/* serialized: magic "FFRFSTAT" | u32 version | u32 variables | u64 body doubles | u64 GUID hash |
 * u64 FNV-1a 64 of the rest | then doubles: start_time, stop_time, has_stop, mode, initialized, body_terms,
 * the failure text (FMU_MESSAGE bytes), values, initialized_with, the body state */
#define STATE_HEAD 40
#define STATE_SCALARS 6

static uint64_t hash_bytes(const unsigned char *p, size_t n)
{
    uint64_t h = 0xCBF29CE484222325ull;
    for (size_t i = 0; i < n; i++)
        h = (h ^ p[i]) * 0x100000001B3ull;
    return h;
}

size_t model_serialized_size(const fmu_instance *m)
{
    size_t body = m->body ? m->state_size : 0;
    return STATE_HEAD + 8 * STATE_SCALARS + FMU_MESSAGE + 8 * (2 * (size_t)m->desc.n_vars + body);
}

static void put64(unsigned char *p, uint64_t v)
{
    for (int i = 0; i < 8; i++)
        p[i] = (unsigned char)(v >> (8 * i));
}

static uint64_t get64(const unsigned char *p)
{
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--)
        v = (v << 8) | p[i];
    return v;
}

void model_serialize(const fmu_instance *m, unsigned char *out)
{
    const size_t nv = (size_t)m->desc.n_vars, body = m->body ? m->state_size : 0;
    unsigned char *p = out + STATE_HEAD;
    double sc[STATE_SCALARS] = {m->start_time, m->stop_time, m->has_stop, (double)m->mode, m->initialized,
                                m->body ? m->body_terms : -1};
    memcpy(p, sc, sizeof sc);
    p += sizeof sc;
    memset(p, 0, FMU_MESSAGE);
    memcpy(p, m->failure, strlen(m->failure));
    p += FMU_MESSAGE;
    memcpy(p, m->values, 8 * nv);
    p += 8 * nv;
    memcpy(p, m->initialized_with, 8 * nv);
    p += 8 * nv;
    if (body)
        ffrf_body_get_state(m->body, (double *)(void *)p); /* out is malloc'd: aligned, and p is at a multiple of 8 */
    size_t size = model_serialized_size(m);
    memcpy(out, "FFRFSTAT", 8);
    out[8] = FMU_STATE_VERSION;
    out[9] = out[10] = out[11] = 0;
    for (int i = 0; i < 4; i++)
        out[12 + i] = (unsigned char)(nv >> (8 * i));
    put64(out + 16, body);
    put64(out + 24, hash_bytes((const unsigned char *)m->desc.guid, strlen(m->desc.guid)));
    put64(out + 32, hash_bytes(out + STATE_HEAD, size - STATE_HEAD));
}

fmi2Status model_serialized_check(fmu_instance *m, const unsigned char *in, size_t size)
{
    const size_t nv = (size_t)m->desc.n_vars;
    if (!in || size < STATE_HEAD || memcmp(in, "FFRFSTAT", 8) != 0) {
        fmu_log(m, fmi2Error, "this FMU state cannot be restored: not a serialized state of this FMU");
        return fmi2Error;
    }
    uint32_t version = in[8] | (uint32_t)in[9] << 8, n = in[12] | (uint32_t)in[13] << 8 | (uint32_t)in[14] << 16 |
                                                          (uint32_t)in[15] << 24;
    uint64_t body = get64(in + 16);
    if (version != FMU_STATE_VERSION) {
        fmu_log(m, fmi2Error, "this FMU state cannot be restored: FMU state version %u is not %d", version,
                FMU_STATE_VERSION);
        return fmi2Error;
    }
    if (get64(in + 24) != hash_bytes((const unsigned char *)m->desc.guid, strlen(m->desc.guid)) || n != nv) {
        fmu_log(m, fmi2Error, "this FMU state cannot be restored: it belongs to another FMU (%u values, this FMU has %u)",
                n, (unsigned)nv);
        return fmi2Error;
    }
    size_t expect = STATE_HEAD + 8 * STATE_SCALARS + FMU_MESSAGE + 8 * (2 * nv + (size_t)(body < ((uint64_t)1 << 32) ? body : 0));
    if (body >= ((uint64_t)1 << 32) || size != expect || get64(in + 32) != hash_bytes(in + STATE_HEAD, size - STATE_HEAD)) {
        fmu_log(m, fmi2Error, "this FMU state cannot be restored: it is damaged (%s)",
                size != expect ? "wrong size" : "checksum mismatch");
        return fmi2Error;
    }
    return fmi2OK;
}

/* ------------------------------------------------------------------ FMU state objects */

typedef struct {
    size_t size;
    unsigned char bytes[];
} saved_state;

fmi2Status model_state_get(fmu_instance *m, const char *call, void **state)
{
    if (!model_allowed(m, call, MODES_ANY) || !state)
        return fmi2Error;
    size_t size = model_serialized_size(m);
    saved_state *s = *state;
    if (s && s->size != size) { /* a state given back to be overwritten, of another size: a fresh one */
        free(s);
        s = NULL;
    }
    if (!s)
        s = malloc(sizeof *s + size);
    if (!s) {
        fmu_log(m, fmi2Error, "%s: out of memory", call);
        return fmi2Error;
    }
    s->size = size;
    model_serialize(m, s->bytes);
    *state = s;
    return fmi2OK;
}

fmi2Status model_state_set(fmu_instance *m, const char *call, const void *state)
{
    if (!model_allowed(m, call, MODES_ANY))
        return fmi2Error;
    if (!state) {
        fmu_log(m, fmi2Error, "%s: NULL state", call);
        return fmi2Error;
    }
    const saved_state *s = state;
    return model_deserialize(m, s->bytes, s->size);
}

void model_state_free(void **state)
{
    if (state) {
        free(*state);
        *state = NULL;
    }
}

fmi2Status model_state_size(fmu_instance *m, const char *call, const void *state, size_t *size)
{
    if (!model_allowed(m, call, MODES_ANY) || !state || !size)
        return fmi2Error;
    *size = ((const saved_state *)state)->size;
    return fmi2OK;
}

fmi2Status model_state_serialize(fmu_instance *m, const char *call, const void *state, unsigned char *out, size_t size)
{
    if (!model_allowed(m, call, MODES_ANY) || !state || !out)
        return fmi2Error;
    const saved_state *s = state;
    if (size < s->size) {
        fmu_log(m, fmi2Error, "%s: buffer of %zu bytes, the state needs %zu", call, size, s->size);
        return fmi2Error;
    }
    memcpy(out, s->bytes, s->size);
    return fmi2OK;
}

fmi2Status model_state_deserialize(fmu_instance *m, const char *call, const unsigned char *in, size_t size, void **state)
{
    if (!model_allowed(m, call, MODES_ANY) || !state || (!in && size))
        return fmi2Error;
    /* checked here (version, FMU, size, checksum): a damaged state is refused now, not when it is set */
    if (model_serialized_check(m, in, size) != fmi2OK)
        return fmi2Error;
    saved_state *s = malloc(sizeof *s + size);
    if (!s) {
        fmu_log(m, fmi2Error, "%s: out of memory", call);
        return fmi2Error;
    }
    s->size = size;
    if (size)
        memcpy(s->bytes, in, size);
    *state = s;
    return fmi2OK;
}

double model_time(const fmu_instance *m)
{
    return m->body ? m->body->state.t : m->start_time;
}

fmi2Status model_deserialize(fmu_instance *m, const unsigned char *in, size_t size)
{
    const size_t nv = (size_t)m->desc.n_vars;
    if (model_serialized_check(m, in, size) != fmi2OK)
        return fmi2Error;
    uint64_t body = get64(in + 16);
    const unsigned char *p = in + STATE_HEAD;
    double sc[STATE_SCALARS];
    memcpy(sc, p, sizeof sc);
    p += sizeof sc;
    int terms = (int)sc[5];
    if (body) {
        if (terms < 0 || terms >= FMU_TERM_SETS || !m->desc.image[terms]) {
            fmu_log(m, fmi2Error, "this FMU state cannot be restored: unknown term set %d", terms);
            return fmi2Error;
        }
        /* the body of the state's term set, and its parameters, from the state's values */
        double *saved = malloc(8 * nv);
        if (!saved) {
            fmu_log(m, fmi2Error, "%s: out of memory", m->fmi ? "fmi3SetFMUState" : "fmi2SetFMUstate");
            return fmi2Error;
        }
        memcpy(saved, m->values, 8 * nv);
        memcpy(m->values, p + sizeof(double) * 0 + FMU_MESSAGE, 8 * nv);
        char why[512];
        int bad = make_body(m, why, sizeof why);
        if (!bad && m->state_size != body) {
            snprintf(why, sizeof why, "its body has %llu state entries, this FMU's %llu", (unsigned long long)body,
                     (unsigned long long)m->state_size);
            bad = 1;
        }
        if (bad) {
            memcpy(m->values, saved, 8 * nv);
            free(saved);
            fmu_log(m, fmi2Error, "this FMU state cannot be restored: %s", why);
            return fmi2Error;
        }
        free(saved);
    }
    m->start_time = sc[0];
    m->stop_time = sc[1];
    m->has_stop = sc[2] != 0.0;
    m->mode = (fmu_mode)(int)sc[3];
    m->initialized = sc[4] != 0.0;
    memcpy(m->failure, p, FMU_MESSAGE);
    m->failure[FMU_MESSAGE - 1] = 0;
    p += FMU_MESSAGE;
    memcpy(m->values, p, 8 * nv);
    p += 8 * nv;
    memcpy(m->initialized_with, p, 8 * nv);
    p += 8 * nv;
    if (body) {
        double *tmp = m->end_state; /* p may be unaligned in a host's buffer */
        memcpy(tmp, p, 8 * (size_t)body);
        if (ffrf_body_set_state(m->body, tmp, (size_t)body) != 0) { /* checked above: a foreign factorization */
            fmu_log(m, fmi2Error, "this FMU state cannot be restored: the body refused its state (its "
                    "factorization's pivots are out of range)");
            m->initialized = 0;
            m->failure[0] = 0;
            snprintf(m->failure, sizeof m->failure, "%s: the body refused the state", m->fmi ? "fmi3SetFMUState" : "fmi2SetFMUstate");
            return fmi2Error;
        }
        ffrf_body_record(m->body, m->row);
    }
    m->discarded[0] = 0; /* a restored state is a fresh start from its time */
    m->have_last = 0;    /* derivatives need a doStep from it */
    return fmi2OK;
}
