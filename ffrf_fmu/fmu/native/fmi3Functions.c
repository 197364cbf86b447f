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

#include "fmi3_types.h"
#include "fmi3Functions.h"
#include "model.h"

#define VR_TIME 0u
#define M(instance) ((fmu_instance *)(instance)) /* the model's instance: the first member of an fmi3_instance */

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

static fmi3_instance *allowed(fmi3Instance instance, const char *call, int modes)
{
    return model_allowed(M(instance), call, modes) ? (fmi3_instance *)instance : NULL;
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
    return status3(model_set_logging(M(instance), "fmi3SetDebugLogging", loggingOn != fmi3False, nCategories, categories));
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
    m->fmi = "fmi3";
    m->sink = sink;
    x->log = logMessage;
    x->env = instanceEnvironment;
    m->log_categories = model_log_categories(loggingOn != fmi3False);
    if (model_instantiate(m, "fmi3InstantiateCoSimulation", instanceName, resourcePath, instantiationToken,
                          "instantiation token",
                          eventModeUsed ? "this FMU has no event mode (hasEventMode=false): eventModeUsed must be false"
                                        : NULL) != fmi2OK)
        goto fail;
    if (build_arrays(x)) {
        fmu_log(m, fmi2Error, "fmi3InstantiateCoSimulation: out of memory");
        goto fail;
    }
    if (nRequiredIntermediateVariables)
        fmu_log(m, fmi2Warning, "fmi3InstantiateCoSimulation: %zu required intermediate variable(s) ignored: this FMU "
                "provides no intermediate update", nRequiredIntermediateVariables);
    return x;
fail:
    free_instance(x);
    return NULL;
}

/* an instantiation this FMU does not provide: NULL, with the reason to logMessage */
static fmi3Instance no_instance(const char *call, fmi3InstanceEnvironment env, fmi3LogMessageCallback logMessage)
{
    char text[96];
    snprintf(text, sizeof text, "%s: this FMU supports co-simulation only", call);
    if (logMessage)
        logMessage(env, fmi3Error, "logStatusError", text);
    return NULL;
}

/* the arguments of the other instantiations are unused: they are refused whatever they are */
#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-parameter"
#endif
fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage)
{
    return no_instance("fmi3InstantiateModelExchange", instanceEnvironment, logMessage);
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption)
{
    return no_instance("fmi3InstantiateScheduledExecution", instanceEnvironment, logMessage);
}
#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif

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
    fmi2Status s = model_setup_experiment(M(instance), "fmi3EnterInitializationMode", startTime,
                                          stopTimeDefined != fmi3False, stopTime);
    return status3(s == fmi2OK ? model_enter_initialization(M(instance), "fmi3EnterInitializationMode") : s);
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    return status3(model_exit_initialization(M(instance), "fmi3ExitInitializationMode"));
}

fmi3Status fmi3Terminate(fmi3Instance instance)
{
    return status3(model_terminate(M(instance), "fmi3Terminate"));
}

fmi3Status fmi3Reset(fmi3Instance instance)
{
    return status3(model_reset(M(instance), "fmi3Reset"));
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

/* The get and set calls of the types this FMU has: the references checked (known, of the type, nValues their
 * elements), the mode and the array, then each variable's run of scalars through the model. as: AS_FLOAT64 or
 * AS_INT32 (values' elements). Only fmi3GetFloat64 takes time. */
static fmi3Status get_set(fmi3Instance instance, const char *call, int set, int as, const fmi3ValueReference vr[],
                         size_t nvr, void *values, size_t nValues)
{
    fmi3_instance *x = (fmi3_instance *)instance;
    const int type = as == AS_FLOAT64 ? T_FLOAT64 : T_INT32;
    size_t total;
    if (!x || checked_refs(x, call, vr, nvr, type, NULL, nValues, type == T_FLOAT64 && !set, &total) ||
        !allowed(instance, call, set ? MODES_SET : MODES_GET))
        return fmi3Error;
    if (total && !values) {
        fmu_log(&x->m, fmi2Error, "%s: NULL array for %zu values", call, total);
        return fmi3Error;
    }
    char *at = values;
    const size_t width = as == AS_FLOAT64 ? sizeof(fmi3Float64) : sizeof(fmi3Int32);
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] == VR_TIME) {
            *(fmi3Float64 *)at = model_time(&x->m);
            at += width;
            continue;
        }
        const fmi2ValueReference *scalar = &x->scalar[x->first[vr[i] - 1]];
        const size_t n = (size_t)x->count[vr[i] - 1];
        fmi2Status s = set ? model_set_scalars(&x->m, call, scalar, n, as, at) : model_get_scalars(&x->m, scalar, n, as, at);
        if (s != fmi2OK)
            return status3(s);
        at += n * width;
    }
    return fmi3OK;
}

#define GET_SET(NAME, CONST, T, SET, AS)                                                                       \
    fmi3Status NAME(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, \
                    CONST T values[], size_t nValues)                                                           \
    {                                                                                                           \
        return get_set(instance, #NAME, SET, AS, valueReferences, nValueReferences, (void *)values, nValues);   \
    }

GET_SET(fmi3GetFloat64, , fmi3Float64, 0, AS_FLOAT64)
GET_SET(fmi3SetFloat64, const, fmi3Float64, 1, AS_FLOAT64)
GET_SET(fmi3GetInt32, , fmi3Int32, 0, AS_INT32)
GET_SET(fmi3SetInt32, const, fmi3Int32, 1, AS_INT32)

/* no variables of the other types: any reference is refused, naming it */
#define NO_GET(NAME, T)                                                                                          \
    fmi3Status NAME(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,  \
                    T values[], size_t nValues)                                                                  \
    {                                                                                                            \
        (void)values;                                                                                            \
        (void)nValues;                                                                                           \
        return no_values(instance, #NAME, valueReferences, nValueReferences, MODES_GET);                         \
    }
#define NO_SET(NAME, T)                                                                                          \
    fmi3Status NAME(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,  \
                    const T values[], size_t nValues)                                                            \
    {                                                                                                            \
        (void)values;                                                                                            \
        (void)nValues;                                                                                           \
        return no_values(instance, #NAME, valueReferences, nValueReferences, MODES_SET);                         \
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
    return no_values(instance, "fmi3GetBinary", valueReferences, nValueReferences, MODES_GET);
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues)
{
    (void)valueSizes;
    (void)values;
    (void)nValues;
    return no_values(instance, "fmi3SetBinary", valueReferences, nValueReferences, MODES_SET);
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Clock values[])
{
    (void)values;
    return no_values(instance, "fmi3GetClock", valueReferences, nValueReferences, MODES_GET);
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Clock values[])
{
    (void)values;
    return no_values(instance, "fmi3SetClock", valueReferences, nValueReferences, MODES_SET);
}

/* ------------------------------------------------------------------ not provided: fmi3Error with the reason */

static fmi3Status refused(fmi3Instance instance, const char *call, const char *why)
{
    return status3(model_refused(M(instance), call, why));
}

/* the arguments of the calls below are unused: each call is refused whatever they are */
#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-parameter"
#endif

#define CO_SIMULATION_ONLY "this FMU supports co-simulation without event mode only"

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                               size_t *nDependencies)
{
    return refused(instance, "fmi3GetNumberOfVariableDependencies",
                   "providesPerElementDependencies=false: the dependencies are the ModelStructure's (every output on every input)");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies)
{
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
    return refused(instance, "fmi3GetIntervalDecimal", NO_CLOCKS);
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[])
{
    return refused(instance, "fmi3GetIntervalFraction", NO_CLOCKS);
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, fmi3Float64 shifts[])
{
    return refused(instance, "fmi3GetShiftDecimal", NO_CLOCKS);
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[])
{
    return refused(instance, "fmi3GetShiftFraction", NO_CLOCKS);
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, const fmi3Float64 intervals[])
{
    return refused(instance, "fmi3SetIntervalDecimal", NO_CLOCKS);
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[])
{
    return refused(instance, "fmi3SetIntervalFraction", NO_CLOCKS);
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, const fmi3Float64 shifts[])
{
    return refused(instance, "fmi3SetShiftDecimal", NO_CLOCKS);
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
{
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
    return refused(instance, "fmi3UpdateDiscreteStates", CO_SIMULATION_ONLY);
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance)
{
    return refused(instance, "fmi3EnterContinuousTimeMode", CO_SIMULATION_ONLY);
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation)
{
    return refused(instance, "fmi3CompletedIntegratorStep", CO_SIMULATION_ONLY);
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time)
{
    return refused(instance, "fmi3SetTime", CO_SIMULATION_ONLY);
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[], size_t n)
{
    return refused(instance, "fmi3SetContinuousStates", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[], size_t n)
{
    return refused(instance, "fmi3GetContinuousStateDerivatives", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t n)
{
    return refused(instance, "fmi3GetEventIndicators", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[], size_t n)
{
    return refused(instance, "fmi3GetContinuousStates", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[], size_t n)
{
    return refused(instance, "fmi3GetNominalsOfContinuousStates", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators)
{
    return refused(instance, "fmi3GetNumberOfEventIndicators", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates)
{
    return refused(instance, "fmi3GetNumberOfContinuousStates", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[],
                                    size_t nValues)
{
    return refused(instance, "fmi3GetOutputDerivatives", "maxOutputDerivativeOrder is 0");
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime)
{
    return refused(instance, "fmi3ActivateModelPartition", CO_SIMULATION_ONLY);
}
#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif

/* ------------------------------------------------------------------ FMU state (model.c model_state_*) */

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    return status3(model_state_get(M(instance), "fmi3GetFMUState", FMUState));
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState)
{
    return status3(model_state_set(M(instance), "fmi3SetFMUState", FMUState));
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    (void)instance;
    model_state_free(FMUState);
    return fmi3OK;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size)
{
    return status3(model_state_size(M(instance), "fmi3SerializedFMUStateSize", FMUState, size));
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[], size_t size)
{
    return status3(model_state_serialize(M(instance), "fmi3SerializeFMUState", FMUState, serializedState, size));
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState)
{
    return status3(model_state_deserialize(M(instance), "fmi3DeserializeFMUState", serializedState, size, FMUState));
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

/* A directional (adjoint 0) or adjoint (1) derivative: J seed into sensitivity, or seed^T J (model.c
 * model_adjoint_derivative), over the scalars of the arrays' references. */
static fmi3Status derivative(fmi3Instance instance, const char *call, int meaning, int adjoint,
                             const fmi3ValueReference unknowns[], size_t nUnknowns, const fmi3ValueReference knowns[],
                             size_t nKnowns, const fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[],
                             size_t nSensitivity)
{
    fmi3_instance *x = allowed(instance, call, MODE_STEP | MODE_INITIALIZATION); /* the model says why not in init */
    fmi2ValueReference *u, *k;
    size_t nu, nk;
    if (!x || derivative_refs(x, call, unknowns, nUnknowns, knowns, nKnowns, &u, &nu, &k, &nk))
        return fmi3Error;
    const size_t n_in = adjoint ? nu : nk, n_out = adjoint ? nk : nu; /* seed, sensitivity */
    fmi2Status s = fmi2Error;
    if (nSeed != n_in || nSensitivity != n_out)
        fmu_log(&x->m, fmi2Error, "%s: the %s hold %zu value(s) and the %s %zu: nSeed = %zu and nSensitivity = %zu must "
                "be those", call, adjoint ? "unknowns" : "knowns", n_in, adjoint ? "knowns" : "unknowns", n_out, nSeed,
                nSensitivity);
    else if ((n_in && !seed) || (n_out && !sensitivity))
        fmu_log(&x->m, fmi2Error, "%s: NULL seed or sensitivity array", call);
    else if (adjoint)
        s = model_adjoint_derivative(&x->m, call, meaning, u, nu, k, nk, seed, sensitivity);
    else
        s = model_directional_derivative(&x->m, meaning, u, nu, k, nk, seed, sensitivity);
    free(u);
    free(k);
    return status3(s);
}

/* FMI 3.0's meaning (model.h DERIV_FMI): the partial derivatives at the communication point, zero (no output
 * depends directly on an input); the adjoint likewise. Step Mode only. */
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
{
    return derivative(instance, "fmi3GetDirectionalDerivative", DERIV_FMI, 0, unknowns, nUnknowns, knowns, nKnowns, seed,
                       nSeed, sensitivity, nSensitivity);
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
{
    return derivative(instance, "fmi3GetAdjointDerivative", DERIV_FMI, 1, unknowns, nUnknowns, knowns, nKnowns, seed, nSeed,
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
    return derivative(instance, "ffrf3GetStepDirectionalDerivative", DERIV_STEP, 0, unknowns, nUnknowns, knowns, nKnowns,
                       seed, nSeed, sensitivity, nSensitivity);
}

fmi3Status ffrf3GetStepAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                         const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                         size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
{
    return derivative(instance, "ffrf3GetStepAdjointDerivative", DERIV_STEP, 1, unknowns, nUnknowns, knowns, nKnowns, seed,
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
    fmi2Status s = model_do_step(&x->m, "fmi3DoStep", currentCommunicationPoint, communicationStepSize);
    if (lastSuccessfulTime) /* the body's time: t_c + H, or t_c after a discard */
        *lastSuccessfulTime = x->m.body ? model_time(&x->m) : currentCommunicationPoint;
    return status3(s);
}
