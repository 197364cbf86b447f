/* FMI 3.0 co-simulation entry points of the body FMU: the twin of fmi2Functions.c over the same model
 * interface (model.h), as the Modelica Association's Reference-FMUs keep fmi2Functions.c and
 * fmi3Functions.c over one model. It is compiled into its own binary (fmu/native/build.py, fmi=3): the
 * FMI 3.0 FMU exports the fmi3 functions only.
 *
 * What FMI 3.0 changes here:
 * - variables are arrays: the FMI 3.0 variable k >= 1 is the run of consecutive FMI 2.0 scalars of one
 *   name (`tip.r[1..3]` is `tip.r` with Dimension 3, `tip.R[i,j]` is `tip.R` [3,3] in row-major order,
 *   the order of the scalars); value reference 0 is `time`, the independent variable. The grouping
 *   rule is fmu/native/__init__.py `fmi3_variables`, written the same way in `build_arrays` below.
 * - messages go to the instance's logMessage callback (model.c fmu_log through `sink`), with the fmi3
 *   function names; statuses have the same values as FMI 2.0's (fmi3OK = fmi2OK ... fmi3Fatal = fmi2Fatal).
 * - directional derivatives take the array references (every element, in order), and the adjoint
 *   derivative is the transposed product (one directional derivative per known element: docs/fmu.md).
 * Co-simulation only, no event mode, no intermediate update (docs/fmu.md says why): every other function
 * exists (hosts look each symbol up) and returns fmi3Error with a message. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* the standard's headers as published: their preemption callbacks are declared without a prototype */
#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wstrict-prototypes"
#endif
#include "fmi3Functions.h"
#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif
#include "model.h"

#define ANY_MODE (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP | MODE_TERMINATED | MODE_ERROR)
#define GET_MODES (MODE_INITIALIZATION | MODE_STEP | MODE_TERMINATED | MODE_ERROR)
#define SET_MODES (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP)
#define VR_TIME 0u

/* one FMI 3.0 instance: the model's instance first (model.c sees only it), then what FMI 3.0 adds */
typedef struct {
    fmu_instance m;
    fmi3LogMessageCallback log;
    fmi3InstanceEnvironment env;
    int n_arrays;                 /* FMI 3.0 variables but time: value references 1..n_arrays */
    int *first, *count;           /* [n_arrays] their scalars: first model value reference, number */
    fmi2ValueReference *scalar;   /* [n_vars] 0, 1, ...: the model's references of a run of scalars */
} fmi3_instance;

static fmi3Status status3(fmi2Status s)
{
    return (fmi3Status)s; /* same values: OK 0, Warning 1, Discard 2, Error 3, Fatal 4 */
}

static void sink(void *inst, int status, const char *category, const char *message)
{
    fmi3_instance *x = inst;
    if (x->log)
        x->log(x->env, (fmi3Status)status, category, message);
}

static const char *mode_name(fmu_mode mode)
{
    switch (mode) {
    case MODE_INSTANTIATED:
        return "instantiated (before fmi3EnterInitializationMode)";
    case MODE_INITIALIZATION:
        return "in initialization mode";
    case MODE_STEP:
        return "in step mode";
    case MODE_TERMINATED:
        return "terminated (after fmi3Terminate)";
    default:
        return "in error (a failed instantiation or initialization: reset or free it)";
    }
}

static fmi3_instance *allowed(fmi3Instance c, const char *call, int modes)
{
    fmi3_instance *x = (fmi3_instance *)c;
    if (!x)
        return NULL;
    if (!(x->m.mode & modes)) {
        fmu_log(&x->m, fmi2Error, "%s is not allowed when the FMU is %s", call, mode_name(x->m.mode));
        return NULL;
    }
    return x;
}

/* the base of a scalar's name: up to its first '[' (`tip.R[1,2]` -> `tip.R`) */
static size_t base_length(const char *name)
{
    const char *b = strchr(name, '[');
    return b ? (size_t)(b - name) : strlen(name);
}

/* the FMI 3.0 variables: runs of consecutive scalars with one base name and type */
static int build_arrays(fmi3_instance *x)
{
    const fmu_description *d = &x->m.desc;
    x->first = malloc(sizeof(int) * (size_t)(d->n_vars ? d->n_vars : 1));
    x->count = malloc(sizeof(int) * (size_t)(d->n_vars ? d->n_vars : 1));
    x->scalar = malloc(sizeof(fmi2ValueReference) * (size_t)(d->n_vars ? d->n_vars : 1));
    if (!x->first || !x->count || !x->scalar)
        return -1;
    x->n_arrays = 0;
    for (int i = 0; i < d->n_vars; i++) {
        x->scalar[i] = (fmi2ValueReference)i;
        const fmu_variable *v = &d->vars[i];
        if (x->n_arrays) {
            const fmu_variable *f = &d->vars[x->first[x->n_arrays - 1]];
            size_t n = base_length(v->name);
            if (strchr(v->name, '[') && n == base_length(f->name) && strncmp(v->name, f->name, n) == 0 &&
                v->type == f->type && v->causality == f->causality) {
                x->count[x->n_arrays - 1]++;
                continue;
            }
        }
        x->first[x->n_arrays] = i;
        x->count[x->n_arrays] = 1;
        x->n_arrays++;
    }
    return 0;
}

static void free_instance(fmi3_instance *x)
{
    model_free(&x->m);
    free(x->first);
    free(x->count);
    free(x->scalar);
    free(x);
}

/* ------------------------------------------------------------------ instance */

const char *fmi3GetVersion(void)
{
    return fmi3Version;
}

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[])
{
    (void)nCategories;
    (void)categories;
    fmi3_instance *x = allowed(instance, "fmi3SetDebugLogging", ANY_MODE);
    if (!x)
        return fmi3Error;
    x->m.logging = loggingOn != fmi3False;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate)
{
    (void)visible;
    (void)earlyReturnAllowed; /* never returns early: doStep is synchronous and ends at t_c + H */
    (void)requiredIntermediateVariables;
    (void)intermediateUpdate; /* providesIntermediateUpdate=false: never called */
    fmi3_instance *x = calloc(1, sizeof *x);
    if (!x)
        return NULL;
    fmu_instance *m = &x->m;
    const char *name = instanceName ? instanceName : "";
    m->name = malloc(strlen(name) + 1);
    if (!m->name) {
        free(x);
        return NULL;
    }
    strcpy(m->name, name);
    m->fmi = "fmi3";
    m->sink = sink;
    x->log = logMessage;
    x->env = instanceEnvironment;
    m->logging = loggingOn != fmi3False;
    m->mode = MODE_ERROR;
    char err[4200], path[4096];
    if (eventModeUsed) {
        fmu_log(m, fmi2Error, "fmi3InstantiateCoSimulation: this FMU has no event mode (hasEventMode=false): "
                "eventModeUsed must be false");
        goto fail;
    }
    if (nRequiredIntermediateVariables)
        fmu_log(m, fmi2Warning, "fmi3InstantiateCoSimulation: %zu required intermediate variable(s) ignored: this FMU "
                "provides no intermediate update", nRequiredIntermediateVariables);
    if (fmu_resource_path(resourcePath, path, sizeof path, err, sizeof err) ||
        fmu_description_load(&m->desc, path, err, sizeof err)) {
        fmu_log(m, fmi2Error, "fmi3InstantiateCoSimulation: %s", err);
        goto fail;
    }
    if (!instantiationToken || strcmp(instantiationToken, m->desc.guid) != 0) {
        fmu_log(m, fmi2Error, "fmi3InstantiateCoSimulation: wrong instantiation token %s: this FMU (%s) has %s",
                instantiationToken ? instantiationToken : "(NULL)", m->desc.description, m->desc.guid);
        goto fail;
    }
    if (build_arrays(x)) {
        fmu_log(m, fmi2Error, "fmi3InstantiateCoSimulation: out of memory");
        goto fail;
    }
    if (model_setup(m) != fmi2OK)
        goto fail;
    return x;
fail:
    free_instance(x);
    return NULL;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage)
{
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    if (logMessage)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateModelExchange: this FMU supports co-simulation only");
    (void)instanceName;
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)instanceName;
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    (void)clockUpdate;
    (void)lockPreemption;
    (void)unlockPreemption;
    if (logMessage)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateScheduledExecution: this FMU supports co-simulation only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance)
{
    if (instance)
        free_instance((fmi3_instance *)instance);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    (void)toleranceDefined;
    (void)tolerance;
    fmi3_instance *x = allowed(instance, "fmi3EnterInitializationMode", MODE_INSTANTIATED);
    if (!x)
        return fmi3Error;
    x->m.start_time = startTime;
    x->m.has_stop = stopTimeDefined != fmi3False;
    x->m.stop_time = stopTime;
    x->m.mode = MODE_INITIALIZATION;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    fmi3_instance *x = allowed(instance, "fmi3ExitInitializationMode", MODE_INITIALIZATION);
    return x ? status3(model_exit_initialization(&x->m)) : fmi3Error;
}

fmi3Status fmi3Terminate(fmi3Instance instance)
{
    fmi3_instance *x = allowed(instance, "fmi3Terminate", MODE_STEP | MODE_INITIALIZATION);
    if (!x)
        return fmi3Error;
    x->m.mode = MODE_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance)
{
    fmi3_instance *x = allowed(instance, "fmi3Reset", ANY_MODE);
    if (!x)
        return fmi3Error;
    model_reset(&x->m);
    return fmi3OK;
}

/* ------------------------------------------------------------------ values */

enum { T_FLOAT64 = TYPE_REAL, T_INT32 = TYPE_INTEGER, T_OTHER = 9 };

/* Every value reference exists and is of the call's type, and nValues is the number of their elements
 * (checked first: a bad reference is named whatever the state); then the state. 0 or -1 (logged). */
static int checked_refs(fmi3_instance *x, const char *call, const fmi3ValueReference vr[], size_t nvr, int type,
                        const char *type_name, size_t n_values, int with_time, size_t *total)
{
    fmu_instance *m = &x->m;
    if (nvr && !vr) {
        fmu_log(m, fmi2Error, "%s: NULL value references for %zu values", call, nvr);
        return -1;
    }
    char list[512] = "";
    size_t k = 0, bad = 0, n = 0;
    for (size_t i = 0; i < nvr; i++)
        if (vr[i] > (fmi3ValueReference)x->n_arrays && bad++ < 6)
            k += (size_t)snprintf(list + k, k < sizeof list ? sizeof list - k : 0, "%s%u", bad > 1 ? ", " : "", vr[i]);
    if (bad) {
        fmu_log(m, fmi2Error, "%s: unknown value reference(s) [%s%s] (this FMU has 0..%d)", call, list,
                bad > 6 ? ", ..." : "", x->n_arrays);
        return -1;
    }
    const char *want = type == T_FLOAT64 ? "Float64" : type == T_INT32 ? "Int32" : type_name;
    for (size_t i = 0; i < nvr; i++) {
        int is_time = vr[i] == VR_TIME;
        const fmu_variable *v = is_time ? NULL : &m->desc.vars[x->first[vr[i] - 1]];
        int vt = is_time ? T_FLOAT64 : v->type;
        if ((vt != type || (is_time && !with_time)) && bad++ < 6)
            k += (size_t)snprintf(list + k, k < sizeof list ? sizeof list - k : 0, "%s%u (%.*s: %s)",
                                  bad > 1 ? ", " : "", vr[i], is_time ? 4 : (int)base_length(v->name),
                                  is_time ? "time" : v->name,
                                  is_time && vt == type ? "the independent variable" : vt == T_FLOAT64 ? "Float64" : "Int32");
        n += is_time ? 1 : (size_t)x->count[vr[i] - 1];
    }
    if (bad) {
        fmu_log(m, fmi2Error, "%s: value reference(s) %s are not %s%s", call, list,
                type == T_FLOAT64 && !with_time ? "Float64 variables this call takes" : want,
                type == T_OTHER ? " (this FMU has Float64 and Int32 variables only)" : "");
        return -1;
    }
    if (n != n_values) {
        fmu_log(m, fmi2Error, "%s: nValues = %zu, but the %zu value reference(s) hold %zu value(s)", call, n_values,
                nvr, n);
        return -1;
    }
    *total = n;
    return 0;
}

static fmi3Status no_values(fmi3Instance instance, const char *call, const fmi3ValueReference vr[], size_t nvr,
                            int modes)
{
    fmi3_instance *x = (fmi3_instance *)instance;
    size_t total;
    if (!x || checked_refs(x, call, vr, nvr, T_OTHER, call + 7, 0, 0, &total) || !allowed(instance, call, modes))
        return fmi3Error;
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          fmi3Float64 values[], size_t nValues)
{
    fmi3_instance *x = (fmi3_instance *)instance;
    size_t total;
    if (!x || checked_refs(x, "fmi3GetFloat64", valueReferences, nValueReferences, T_FLOAT64, "Float64", nValues, 1,
                           &total) || !allowed(instance, "fmi3GetFloat64", GET_MODES))
        return fmi3Error;
    if (total && !values) {
        fmu_log(&x->m, fmi2Error, "fmi3GetFloat64: NULL array for %zu values", total);
        return fmi3Error;
    }
    size_t at = 0;
    for (size_t i = 0; i < nValueReferences; i++) {
        fmi3ValueReference v = valueReferences[i];
        if (v == VR_TIME) {
            values[at++] = x->m.body ? model_time(&x->m) : x->m.start_time;
            continue;
        }
        int first = x->first[v - 1], n = x->count[v - 1];
        fmi2Status s = model_get_real(&x->m, &x->scalar[first], (size_t)n, values + at);
        if (s != fmi2OK)
            return status3(s);
        at += (size_t)n;
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          const fmi3Float64 values[], size_t nValues)
{
    fmi3_instance *x = (fmi3_instance *)instance;
    size_t total;
    if (!x || checked_refs(x, "fmi3SetFloat64", valueReferences, nValueReferences, T_FLOAT64, "Float64", nValues, 0,
                           &total) || !allowed(instance, "fmi3SetFloat64", SET_MODES))
        return fmi3Error;
    if (total && !values) {
        fmu_log(&x->m, fmi2Error, "fmi3SetFloat64: NULL array for %zu values", total);
        return fmi3Error;
    }
    size_t at = 0;
    for (size_t i = 0; i < nValueReferences; i++) {
        int first = x->first[valueReferences[i] - 1], n = x->count[valueReferences[i] - 1];
        fmi2Status s = model_set_real(&x->m, &x->scalar[first], (size_t)n, values + at);
        if (s != fmi2OK)
            return status3(s);
        at += (size_t)n;
    }
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Int32 values[], size_t nValues)
{
    fmi3_instance *x = (fmi3_instance *)instance;
    size_t total;
    if (!x || checked_refs(x, "fmi3GetInt32", valueReferences, nValueReferences, T_INT32, "Int32", nValues, 0, &total) ||
        !allowed(instance, "fmi3GetInt32", GET_MODES))
        return fmi3Error;
    if (total && !values) {
        fmu_log(&x->m, fmi2Error, "fmi3GetInt32: NULL array for %zu values", total);
        return fmi3Error;
    }
    size_t at = 0;
    for (size_t i = 0; i < nValueReferences; i++) {
        int first = x->first[valueReferences[i] - 1], n = x->count[valueReferences[i] - 1];
        fmi2Integer buf[16];
        for (int done = 0; done < n; done += 16) { /* fmi2Integer is int, fmi3Int32 int32_t: copied, not cast */
            int part = n - done < 16 ? n - done : 16;
            fmi2Status s = model_get_integer(&x->m, &x->scalar[first + done], (size_t)part, buf);
            if (s != fmi2OK)
                return status3(s);
            for (int j = 0; j < part; j++)
                values[at++] = (fmi3Int32)buf[j];
        }
    }
    return fmi3OK;
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Int32 values[], size_t nValues)
{
    fmi3_instance *x = (fmi3_instance *)instance;
    size_t total;
    if (!x || checked_refs(x, "fmi3SetInt32", valueReferences, nValueReferences, T_INT32, "Int32", nValues, 0, &total) ||
        !allowed(instance, "fmi3SetInt32", SET_MODES))
        return fmi3Error;
    if (total && !values) {
        fmu_log(&x->m, fmi2Error, "fmi3SetInt32: NULL array for %zu values", total);
        return fmi3Error;
    }
    size_t at = 0;
    for (size_t i = 0; i < nValueReferences; i++) {
        int first = x->first[valueReferences[i] - 1], n = x->count[valueReferences[i] - 1];
        fmi2Integer buf[16];
        for (int done = 0; done < n; done += 16) {
            int part = n - done < 16 ? n - done : 16;
            for (int j = 0; j < part; j++)
                buf[j] = (fmi2Integer)values[at++];
            fmi2Status s = model_set_integer(&x->m, &x->scalar[first + done], (size_t)part, buf);
            if (s != fmi2OK)
                return status3(s);
        }
    }
    return fmi3OK;
}

/* no variables of the other types: any reference is refused, naming it */
#define NO_GET(NAME, T)                                                                                          \
    fmi3Status NAME(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,  \
                    T values[], size_t nValues)                                                                  \
    {                                                                                                            \
        (void)values;                                                                                            \
        (void)nValues;                                                                                           \
        return no_values(instance, #NAME, valueReferences, nValueReferences, GET_MODES);                         \
    }
#define NO_SET(NAME, T)                                                                                          \
    fmi3Status NAME(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,  \
                    const T values[], size_t nValues)                                                            \
    {                                                                                                            \
        (void)values;                                                                                            \
        (void)nValues;                                                                                           \
        return no_values(instance, #NAME, valueReferences, nValueReferences, SET_MODES);                         \
    }

NO_GET(fmi3GetFloat32, fmi3Float32)
NO_GET(fmi3GetInt8, fmi3Int8)
NO_GET(fmi3GetUInt8, fmi3UInt8)
NO_GET(fmi3GetInt16, fmi3Int16)
NO_GET(fmi3GetUInt16, fmi3UInt16)
NO_GET(fmi3GetUInt32, fmi3UInt32)
NO_GET(fmi3GetInt64, fmi3Int64)
NO_GET(fmi3GetUInt64, fmi3UInt64)
NO_GET(fmi3GetBoolean, fmi3Boolean)
NO_GET(fmi3GetString, fmi3String)
NO_SET(fmi3SetFloat32, fmi3Float32)
NO_SET(fmi3SetInt8, fmi3Int8)
NO_SET(fmi3SetUInt8, fmi3UInt8)
NO_SET(fmi3SetInt16, fmi3Int16)
NO_SET(fmi3SetUInt16, fmi3UInt16)
NO_SET(fmi3SetUInt32, fmi3UInt32)
NO_SET(fmi3SetInt64, fmi3Int64)
NO_SET(fmi3SetUInt64, fmi3UInt64)
NO_SET(fmi3SetBoolean, fmi3Boolean)
NO_SET(fmi3SetString, fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         size_t valueSizes[], fmi3Binary values[], size_t nValues)
{
    (void)valueSizes;
    (void)values;
    (void)nValues;
    return no_values(instance, "fmi3GetBinary", valueReferences, nValueReferences, GET_MODES);
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues)
{
    (void)valueSizes;
    (void)values;
    (void)nValues;
    return no_values(instance, "fmi3SetBinary", valueReferences, nValueReferences, SET_MODES);
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Clock values[])
{
    (void)values;
    return no_values(instance, "fmi3GetClock", valueReferences, nValueReferences, GET_MODES);
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Clock values[])
{
    (void)values;
    return no_values(instance, "fmi3SetClock", valueReferences, nValueReferences, SET_MODES);
}

/* ------------------------------------------------------------------ not provided: fmi3Error with the reason */

static fmi3Status refused(fmi3Instance instance, const char *call, const char *why)
{
    fmi3_instance *x = allowed(instance, call, ANY_MODE);
    if (x)
        fmu_log(&x->m, fmi2Error, "%s: %s", call, why);
    return fmi3Error;
}

#define CO_SIMULATION_ONLY "this FMU supports co-simulation without event mode only"

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                               size_t *nDependencies)
{
    (void)valueReference;
    (void)nDependencies;
    return refused(instance, "fmi3GetNumberOfVariableDependencies",
                   "providesPerElementDependencies=false: the dependencies are the ModelStructure's (every output on every input)");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies)
{
    (void)dependent;
    (void)elementIndicesOfDependent;
    (void)independents;
    (void)elementIndicesOfIndependents;
    (void)dependencyKinds;
    (void)nDependencies;
    return refused(instance, "fmi3GetVariableDependencies",
                   "providesPerElementDependencies=false: the dependencies are the ModelStructure's (every output on every input)");
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance)
{
    return refused(instance, "fmi3EnterEventMode", CO_SIMULATION_ONLY " (hasEventMode=false)");
}

fmi3Status fmi3EnterStepMode(fmi3Instance instance)
{
    return refused(instance, "fmi3EnterStepMode", "no event mode (hasEventMode=false): fmi3ExitInitializationMode "
                   "enters step mode");
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance)
{
    return refused(instance, "fmi3EnterConfigurationMode", "no structural parameters");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance)
{
    return refused(instance, "fmi3ExitConfigurationMode", "no structural parameters");
}

#define NO_CLOCKS "no clocks"
fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[])
{
    (void)valueReferences, (void)nValueReferences, (void)intervals, (void)qualifiers;
    return refused(instance, "fmi3GetIntervalDecimal", NO_CLOCKS);
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[])
{
    (void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions, (void)qualifiers;
    return refused(instance, "fmi3GetIntervalFraction", NO_CLOCKS);
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, fmi3Float64 shifts[])
{
    (void)valueReferences, (void)nValueReferences, (void)shifts;
    return refused(instance, "fmi3GetShiftDecimal", NO_CLOCKS);
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[])
{
    (void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions;
    return refused(instance, "fmi3GetShiftFraction", NO_CLOCKS);
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, const fmi3Float64 intervals[])
{
    (void)valueReferences, (void)nValueReferences, (void)intervals;
    return refused(instance, "fmi3SetIntervalDecimal", NO_CLOCKS);
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[])
{
    (void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions;
    return refused(instance, "fmi3SetIntervalFraction", NO_CLOCKS);
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, const fmi3Float64 shifts[])
{
    (void)valueReferences, (void)nValueReferences, (void)shifts;
    return refused(instance, "fmi3SetShiftDecimal", NO_CLOCKS);
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
{
    (void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions;
    return refused(instance, "fmi3SetShiftFraction", NO_CLOCKS);
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance)
{
    return refused(instance, "fmi3EvaluateDiscreteStates", CO_SIMULATION_ONLY);
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime)
{
    (void)discreteStatesNeedUpdate, (void)terminateSimulation, (void)nominalsOfContinuousStatesChanged;
    (void)valuesOfContinuousStatesChanged, (void)nextEventTimeDefined, (void)nextEventTime;
    return refused(instance, "fmi3UpdateDiscreteStates", CO_SIMULATION_ONLY);
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance)
{
    return refused(instance, "fmi3EnterContinuousTimeMode", CO_SIMULATION_ONLY);
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation)
{
    (void)noSetFMUStatePriorToCurrentPoint, (void)enterEventMode, (void)terminateSimulation;
    return refused(instance, "fmi3CompletedIntegratorStep", CO_SIMULATION_ONLY);
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time)
{
    (void)time;
    return refused(instance, "fmi3SetTime", CO_SIMULATION_ONLY);
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[], size_t n)
{
    (void)continuousStates, (void)n;
    return refused(instance, "fmi3SetContinuousStates", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[], size_t n)
{
    (void)derivatives, (void)n;
    return refused(instance, "fmi3GetContinuousStateDerivatives", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t n)
{
    (void)eventIndicators, (void)n;
    return refused(instance, "fmi3GetEventIndicators", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[], size_t n)
{
    (void)continuousStates, (void)n;
    return refused(instance, "fmi3GetContinuousStates", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[], size_t n)
{
    (void)nominals, (void)n;
    return refused(instance, "fmi3GetNominalsOfContinuousStates", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators)
{
    (void)nEventIndicators;
    return refused(instance, "fmi3GetNumberOfEventIndicators", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates)
{
    (void)nContinuousStates;
    return refused(instance, "fmi3GetNumberOfContinuousStates", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[],
                                    size_t nValues)
{
    (void)valueReferences, (void)nValueReferences, (void)orders, (void)values, (void)nValues;
    return refused(instance, "fmi3GetOutputDerivatives", "maxOutputDerivativeOrder is 0");
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime)
{
    (void)clockReference, (void)activationTime;
    return refused(instance, "fmi3ActivateModelPartition", CO_SIMULATION_ONLY);
}

/* ------------------------------------------------------------------ FMU state (model.c model_state_*) */

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    fmi3_instance *x = allowed(instance, "fmi3GetFMUState", ANY_MODE);
    return x && FMUState ? status3(model_state_get(&x->m, "fmi3GetFMUState", FMUState)) : fmi3Error;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState)
{
    fmi3_instance *x = allowed(instance, "fmi3SetFMUState", ANY_MODE);
    return x ? status3(model_state_set(&x->m, "fmi3SetFMUState", FMUState)) : fmi3Error;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    (void)instance;
    model_state_free(FMUState);
    return fmi3OK;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size)
{
    return allowed(instance, "fmi3SerializedFMUStateSize", ANY_MODE) ? status3(model_state_size(FMUState, size))
                                                                     : fmi3Error;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[], size_t size)
{
    fmi3_instance *x = allowed(instance, "fmi3SerializeFMUState", ANY_MODE);
    return x ? status3(model_state_serialize(&x->m, "fmi3SerializeFMUState", FMUState, serializedState, size))
             : fmi3Error;
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState)
{
    fmi3_instance *x = allowed(instance, "fmi3DeserializeFMUState", ANY_MODE);
    return x ? status3(model_state_deserialize(&x->m, "fmi3DeserializeFMUState", serializedState, size, FMUState))
             : fmi3Error;
}

/* ------------------------------------------------------------------ derivatives */

/* the model's scalar references of FMI 3.0 Float64 variables (every element, in order), allocated; NULL (logged)
 * when one is unknown, time or not Float64 */
static fmi2ValueReference *scalars(fmi3_instance *x, const char *call, const fmi3ValueReference vr[], size_t nvr,
                                   size_t *n)
{
    size_t total;
    if (nvr && !vr) {
        fmu_log(&x->m, fmi2Error, "%s: NULL value references for %zu variables", call, nvr);
        return NULL;
    }
    size_t count = 0;
    for (size_t i = 0; i < nvr; i++)
        count += vr[i] >= 1 && vr[i] <= (fmi3ValueReference)x->n_arrays ? (size_t)x->count[vr[i] - 1] : 1;
    if (checked_refs(x, call, vr, nvr, T_FLOAT64, "Float64", count, 0, &total))
        return NULL;
    fmi2ValueReference *out = malloc(sizeof *out * (total ? total : 1));
    if (!out) {
        fmu_log(&x->m, fmi2Error, "%s: out of memory", call);
        return NULL;
    }
    size_t at = 0;
    for (size_t i = 0; i < nvr; i++)
        for (int j = 0; j < x->count[vr[i] - 1]; j++)
            out[at++] = (fmi2ValueReference)(x->first[vr[i] - 1] + j);
    *n = total;
    return out;
}

/* the references and sizes of a derivative call: the scalar lists, or -1 (logged) */
static int derivative_refs(fmi3_instance *x, const char *call, const fmi3ValueReference unknowns[], size_t nUnknowns,
                           const fmi3ValueReference knowns[], size_t nKnowns, fmi2ValueReference **u, size_t *nu,
                           fmi2ValueReference **k, size_t *nk)
{
    *u = scalars(x, call, unknowns, nUnknowns, nu);
    *k = *u ? scalars(x, call, knowns, nKnowns, nk) : NULL;
    if (!*u || !*k) {
        free(*u);
        *u = NULL;
        return -1;
    }
    return 0;
}

static fmi3Status directional(fmi3Instance instance, const char *call, int meaning, const fmi3ValueReference unknowns[],
                              size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                              size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
{
    fmi3_instance *x = allowed(instance, call, MODE_STEP | MODE_INITIALIZATION); /* the model says why not in init */
    fmi2ValueReference *u, *k;
    size_t nu, nk;
    if (!x || derivative_refs(x, call, unknowns, nUnknowns, knowns, nKnowns, &u, &nu, &k, &nk))
        return fmi3Error;
    fmi3Status s = fmi3Error;
    if (nSeed != nk || nSensitivity != nu)
        fmu_log(&x->m, fmi2Error, "%s: the knowns hold %zu value(s) and the unknowns %zu: nSeed = %zu and "
                "nSensitivity = %zu must be those", call, nk, nu, nSeed, nSensitivity);
    else if ((nk && !seed) || (nu && !sensitivity))
        fmu_log(&x->m, fmi2Error, "%s: NULL seed or sensitivity array", call);
    else
        s = status3(model_directional_derivative(&x->m, meaning, u, nu, k, nk, seed, sensitivity));
    free(u);
    free(k);
    return s;
}

/* v^T J: one directional derivative per known element j (the column J e_j, the seed e_j over all the knowns),
 * then its product with the seed v. The columns are those the directional call of the same meaning gives for
 * the same knowns and the unit seeds, to the bit (a step derivative's column costs two re-runs of the last
 * step: docs/fmu.md). */
static fmi3Status adjoint(fmi3Instance instance, const char *call, int meaning, const fmi3ValueReference unknowns[],
                          size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                          size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
{
    fmi3_instance *x = allowed(instance, call, MODE_STEP | MODE_INITIALIZATION); /* the model says why not in init */
    fmi2ValueReference *u, *k;
    size_t nu, nk;
    if (!x || derivative_refs(x, call, unknowns, nUnknowns, knowns, nKnowns, &u, &nu, &k, &nk))
        return fmi3Error;
    fmi3Status s = fmi3Error;
    double *column = NULL, *unit = NULL;
    if (nSeed != nu || nSensitivity != nk) {
        fmu_log(&x->m, fmi2Error, "%s: the unknowns hold %zu value(s) and the knowns %zu: nSeed = %zu and "
                "nSensitivity = %zu must be those", call, nu, nk, nSeed, nSensitivity);
    } else if ((nu && !seed) || (nk && !sensitivity)) {
        fmu_log(&x->m, fmi2Error, "%s: NULL seed or sensitivity array", call);
    } else if (!(column = malloc(sizeof(double) * (nu ? nu : 1))) || !(unit = calloc(nk ? nk : 1, sizeof(double)))) {
        fmu_log(&x->m, fmi2Error, "%s: out of memory", call);
    } else {
        s = fmi3OK;
        for (size_t j = 0; j < nk && s == fmi3OK; j++) { /* J e_j over all the knowns, as the directional call */
            unit[j] = 1.0;
            s = status3(model_directional_derivative(&x->m, meaning, u, nu, k, nk, unit, column));
            unit[j] = 0.0;
            double sum = 0.0;
            for (size_t i = 0; i < nu; i++)
                sum += seed[i] * column[i];
            sensitivity[j] = sum;
        }
    }
    free(unit);
    free(column);
    free(u);
    free(k);
    return s;
}

/* FMI 3.0's meaning (model.h DERIV_FMI): the partial derivatives at the communication point, zero (no output
 * depends directly on an input); the adjoint likewise. Step Mode only. */
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
{
    return directional(instance, "fmi3GetDirectionalDerivative", DERIV_FMI, unknowns, nUnknowns, knowns, nKnowns, seed,
                       nSeed, sensitivity, nSensitivity);
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
{
    return adjoint(instance, "fmi3GetAdjointDerivative", DERIV_FMI, unknowns, nUnknowns, knowns, nKnowns, seed, nSeed,
                   sensitivity, nSensitivity);
}

/* Not FMI functions: the derivatives of the last communication step (model.h DERIV_STEP) and their transposed
 * product, with the arguments and statuses of fmi3GetDirectionalDerivative and fmi3GetAdjointDerivative (docs/fmu.md,
 * "Directional derivatives"). */
FMI3_Export fmi3Status ffrf3GetStepDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[],
                                                         size_t nUnknowns, const fmi3ValueReference knowns[],
                                                         size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
                                                         fmi3Float64 sensitivity[], size_t nSensitivity);
FMI3_Export fmi3Status ffrf3GetStepAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[],
                                                     size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns,
                                                     const fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[],
                                                     size_t nSensitivity);

fmi3Status ffrf3GetStepDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[],
                                             size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns,
                                             const fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[],
                                             size_t nSensitivity)
{
    return directional(instance, "ffrf3GetStepDirectionalDerivative", DERIV_STEP, unknowns, nUnknowns, knowns, nKnowns,
                       seed, nSeed, sensitivity, nSensitivity);
}

fmi3Status ffrf3GetStepAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                         const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                         size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
{
    return adjoint(instance, "ffrf3GetStepAdjointDerivative", DERIV_STEP, unknowns, nUnknowns, knowns, nKnowns, seed,
                   nSeed, sensitivity, nSensitivity);
}

/* ------------------------------------------------------------------ co-simulation */

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint, fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *eventHandlingNeeded,
                      fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    fmi3_instance *x = (fmi3_instance *)instance;
    if (eventHandlingNeeded)
        *eventHandlingNeeded = fmi3False;
    if (terminateSimulation)
        *terminateSimulation = fmi3False;
    if (earlyReturn)
        *earlyReturn = fmi3False;
    if (!x)
        return fmi3Error;
    fmu_instance *m = &x->m;
    fmi2Status s;
    if (m->mode == MODE_TERMINATED) {
        fmu_log(m, fmi2Error, "t = %.6g s: fmi3DoStep after fmi3Terminate (reset or free the instance)",
                currentCommunicationPoint);
        s = fmi2Error;
    } else if (m->mode == MODE_STEP && m->failure[0]) { /* model_do_step names the failed initialization */
        s = model_do_step(m, currentCommunicationPoint, communicationStepSize);
    } else {
        s = allowed(instance, "fmi3DoStep", MODE_STEP) ? model_do_step(m, currentCommunicationPoint,
                                                                       communicationStepSize)
                                                       : fmi2Error;
    }
    if (lastSuccessfulTime) /* the body's time: t_c + H, or t_c after a discard */
        *lastSuccessfulTime = m->body ? model_time(m) : currentCommunicationPoint;
    return status3(s);
}
