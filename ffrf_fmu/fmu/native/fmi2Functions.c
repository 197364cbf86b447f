/* FMI 2.0 co-simulation entry points of the body FMU: a thin translation of the standard's calls onto the
 * model interface (model.h), which checks the instance, the call's state (FMI 2.0 section 4.2.4: a call in the
 * wrong state is fmi2Error with a message) and the value references. Co-simulation only: the model-exchange
 * functions exist (some hosts look every fmi2 symbol up) and return fmi2Error. */
#include <stdlib.h>

#include "fmi2Functions.h"
#include "model.h"

/* the model's instance of a component */
#define M(c) ((fmu_instance *)(c))

const char *fmi2GetTypesPlatform(void)
{
    return fmi2TypesPlatform;
}

const char *fmi2GetVersion(void)
{
    return fmi2Version;
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    return model_set_logging(M(c), "fmi2SetDebugLogging", loggingOn != fmi2False, nCategories, categories);
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    (void)visible;
    fmu_instance *m = calloc(1, sizeof *m);
    if (!m)
        return NULL;
    if (functions)
        m->cb = *functions;
    m->log_categories = model_log_categories(loggingOn != fmi2False);
    if (model_instantiate(m, "fmi2Instantiate", instanceName, fmuResourceLocation, fmuGUID, "GUID",
                          fmuType != fmi2CoSimulation ? "this FMU supports co-simulation only (fmuType fmi2CoSimulation)"
                                                      : NULL) == fmi2OK)
        return m;
    model_free(m);
    free(m);
    return NULL;
}

void fmi2FreeInstance(fmi2Component c)
{
    if (!c)
        return;
    model_free(M(c));
    free(c);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    (void)toleranceDefined;
    (void)tolerance;
    return model_setup_experiment(M(c), "fmi2SetupExperiment", startTime, stopTimeDefined != fmi2False, stopTime);
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    return model_enter_initialization(M(c), "fmi2EnterInitializationMode");
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    return model_exit_initialization(M(c), "fmi2ExitInitializationMode");
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    return model_terminate(M(c), "fmi2Terminate");
}

fmi2Status fmi2Reset(fmi2Component c)
{
    return model_reset(M(c), "fmi2Reset");
}

/* ------------------------------------------------------------------ values (model.c model_get_values, _set_values) */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    return model_get_values(M(c), "fmi2GetReal", TYPE_REAL, vr, nvr, value);
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    return model_get_values(M(c), "fmi2GetInteger", TYPE_INTEGER, vr, nvr, value);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    return model_get_values(M(c), "fmi2GetBoolean", TYPE_BOOLEAN, vr, nvr, value);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    return model_get_values(M(c), "fmi2GetString", TYPE_STRING, vr, nvr, value);
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    return model_set_values(M(c), "fmi2SetReal", TYPE_REAL, vr, nvr, value);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[])
{
    return model_set_values(M(c), "fmi2SetInteger", TYPE_INTEGER, vr, nvr, value);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[])
{
    return model_set_values(M(c), "fmi2SetBoolean", TYPE_BOOLEAN, vr, nvr, value);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[])
{
    return model_set_values(M(c), "fmi2SetString", TYPE_STRING, vr, nvr, value);
}

/* ------------------------------------------------------------------ FMU state (model.c model_state_*) */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    return model_state_get(M(c), "fmi2GetFMUstate", FMUstate);
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    return model_state_set(M(c), "fmi2SetFMUstate", FMUstate);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    (void)c;
    model_state_free(FMUstate);
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size)
{
    return model_state_size(M(c), "fmi2SerializedFMUstateSize", FMUstate, size);
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size)
{
    return model_state_serialize(M(c), "fmi2SerializeFMUstate", FMUstate, (unsigned char *)serializedState, size);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate)
{
    return model_state_deserialize(M(c), "fmi2DeSerializeFMUstate", (const unsigned char *)serializedState, size,
                                   FMUstate);
}

/* ------------------------------------------------------------------ derivatives */

static fmi2Status derivative(fmi2Component c, const char *call, int meaning, const fmi2ValueReference vUnknown_ref[],
                             size_t nUnknown, const fmi2ValueReference vKnown_ref[], size_t nKnown,
                             const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    fmu_instance *m = model_allowed(M(c), call, MODE_STEP | MODE_INITIALIZATION); /* the model says why not in init */
    if (!m)
        return fmi2Error;
    size_t null = nUnknown && (!vUnknown_ref || !dvUnknown) ? nUnknown : nKnown && (!vKnown_ref || !dvKnown) ? nKnown : 0;
    if (null) {
        fmu_log(m, fmi2Error, "%s: NULL array for %zu values", call, null);
        return fmi2Error;
    }
    return model_directional_derivative(m, meaning, vUnknown_ref, nUnknown, vKnown_ref, nKnown, dvKnown, dvUnknown);
}

/* FMI 2.0's meaning (model.h DERIV_FMI): the partial derivatives at the communication point, zero (no output
 * depends directly on an input). Step mode only: in initialization mode the call is refused, naming why. */
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    return derivative(c, "fmi2GetDirectionalDerivative", DERIV_FMI, vUnknown_ref, nUnknown, vKnown_ref, nKnown, dvKnown,
                      dvUnknown);
}

/* Not an FMI function: the derivatives of the last communication step (model.h DERIV_STEP), with
 * fmi2GetDirectionalDerivative's arguments and statuses; exported for the interface-Jacobian master
 * (ffrf_fmu/master/instance.py STEP_DERIVATIVE; docs/fmu.md, "Directional derivatives"). */
FMI2_Export fmi2Status ffrf2GetStepDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                              const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                              const fmi2Real dvKnown[], fmi2Real dvUnknown[]);
fmi2Status ffrf2GetStepDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                  const fmi2ValueReference vKnown_ref[], size_t nKnown, const fmi2Real dvKnown[],
                                  fmi2Real dvUnknown[])
{
    return derivative(c, "ffrf2GetStepDerivative", DERIV_STEP, vUnknown_ref, nUnknown, vKnown_ref, nKnown, dvKnown,
                      dvUnknown);
}

/* ------------------------------------------------------------------ co-simulation */

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    return model_do_step(M(c), "fmi2DoStep", currentCommunicationPoint, communicationStepSize);
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    fmu_instance *m = model_allowed(M(c), "fmi2GetRealStatus", MODE_STEP | MODE_TERMINATED | MODE_ERROR);
    if (!m || !value)
        return fmi2Error;
    if (s != fmi2LastSuccessfulTime || !m->body)
        return model_refused(m, "fmi2GetRealStatus", "only fmi2LastSuccessfulTime is available, after initialization");
    *value = model_time(m);
    return fmi2OK;
}

/* ------------------------------------------------------------------ not provided: fmi2Error with the reason */

/* the arguments of the calls below are unused: each call is refused whatever they are */
#if defined(__GNUC__)
#pragma GCC diagnostic ignored "-Wunused-parameter"
#endif
#define ME_ONLY "this FMU supports co-simulation only"

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    return model_refused(M(c), "fmi2SetRealInputDerivatives", "this FMU does not interpolate inputs "
                         "(canInterpolateInputs=false): set the rates and accelerations as inputs (P.v, P.a, P.w, P.dw)");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    return model_refused(M(c), "fmi2GetRealOutputDerivatives", "maxOutputDerivativeOrder is 0");
}

fmi2Status fmi2CancelStep(fmi2Component c)
{
    return model_refused(M(c), "fmi2CancelStep", "doStep is synchronous (canRunAsynchronuously=false): nothing to cancel");
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    return model_refused(M(c), "fmi2GetStatus", "doStep is synchronous: no pending status");
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    return model_refused(M(c), "fmi2GetIntegerStatus", "no integer status");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    return model_refused(M(c), "fmi2GetBooleanStatus", "no boolean status (doStep never terminates the simulation)");
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    return model_refused(M(c), "fmi2GetStringStatus", "no string status");
}

fmi2Status fmi2EnterEventMode(fmi2Component c)
{
    return model_refused(M(c), "fmi2EnterEventMode", ME_ONLY);
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info)
{
    return model_refused(M(c), "fmi2NewDiscreteStates", ME_ONLY);
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c)
{
    return model_refused(M(c), "fmi2EnterContinuousTimeMode", ME_ONLY);
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation)
{
    return model_refused(M(c), "fmi2CompletedIntegratorStep", ME_ONLY);
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time)
{
    return model_refused(M(c), "fmi2SetTime", ME_ONLY);
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx)
{
    return model_refused(M(c), "fmi2SetContinuousStates", ME_ONLY);
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx)
{
    return model_refused(M(c), "fmi2GetDerivatives", ME_ONLY);
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni)
{
    return model_refused(M(c), "fmi2GetEventIndicators", ME_ONLY);
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx)
{
    return model_refused(M(c), "fmi2GetContinuousStates", ME_ONLY);
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx)
{
    return model_refused(M(c), "fmi2GetNominalsOfContinuousStates", ME_ONLY);
}
