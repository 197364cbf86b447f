/* FMI 2.0 co-simulation entry points of the body FMU: a thin layer that checks the instance, the call's
 * state (FMI 2.0 section 4.2.4: a call in the wrong state is fmi2Error with a message) and the value
 * references, then calls the model interface (model.h). Co-simulation only: the model-exchange functions
 * exist (some hosts look every fmi2 symbol up) and return fmi2Error. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "model.h"

#define ANY_MODE (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP | MODE_TERMINATED | MODE_ERROR)

static const char *mode_name(fmu_mode mode)
{
    switch (mode) {
    case MODE_INSTANTIATED:
        return "instantiated (before fmi2EnterInitializationMode)";
    case MODE_INITIALIZATION:
        return "initialization mode";
    case MODE_STEP:
        return "step mode";
    case MODE_TERMINATED:
        return "terminated (after fmi2Terminate)";
    default:
        return "error";
    }
}

/* the instance, if `call` is allowed in its state (else fmi2Error logged) */
static fmu_instance *allowed(fmi2Component c, const char *call, int modes)
{
    fmu_instance *m = (fmu_instance *)c;
    if (!m)
        return NULL;
    if (!(m->mode & modes)) {
        fmu_log(m, fmi2Error, "%s is not allowed when the FMU is %s", call, mode_name(m->mode));
        return NULL;
    }
    return m;
}

static int null_arrays(fmu_instance *m, const char *call, size_t n, const void *a, const void *b)
{
    if (n && (!a || !b)) {
        fmu_log(m, fmi2Error, "%s: NULL array for %zu values", call, n);
        return 1;
    }
    return 0;
}

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
    (void)nCategories;
    (void)categories;
    fmu_instance *m = allowed(c, "fmi2SetDebugLogging", ANY_MODE);
    if (!m)
        return fmi2Error;
    m->logging = loggingOn != fmi2False;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    (void)visible;
    fmu_instance *m = calloc(1, sizeof *m);
    if (!m)
        return NULL;
    const char *name = instanceName ? instanceName : "";
    m->name = malloc(strlen(name) + 1);
    if (!m->name) {
        free(m);
        return NULL;
    }
    strcpy(m->name, name);
    if (functions)
        m->cb = *functions;
    m->logging = loggingOn != fmi2False;
    m->mode = MODE_ERROR;
    char err[4200], path[4096];
    if (fmuType != fmi2CoSimulation) {
        fmu_log(m, fmi2Error, "fmi2Instantiate: this FMU supports co-simulation only (fmuType fmi2CoSimulation)");
        goto fail;
    }
    if (fmu_resource_path(fmuResourceLocation, path, sizeof path, err, sizeof err) ||
        fmu_description_load(&m->desc, path, err, sizeof err)) {
        fmu_log(m, fmi2Error, "fmi2Instantiate: %s", err);
        goto fail;
    }
    if (!fmuGUID || strcmp(fmuGUID, m->desc.guid) != 0) {
        fmu_log(m, fmi2Error, "fmi2Instantiate: wrong GUID %s: this FMU (%s) has GUID %s", fmuGUID ? fmuGUID : "(NULL)",
                m->desc.description, m->desc.guid);
        goto fail;
    }
    if (model_setup(m) != fmi2OK)
        goto fail;
    return m;
fail:
    model_free(m);
    free(m);
    return NULL;
}

void fmi2FreeInstance(fmi2Component c)
{
    fmu_instance *m = (fmu_instance *)c;
    if (!m)
        return;
    model_free(m);
    free(m);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    (void)toleranceDefined;
    (void)tolerance;
    fmu_instance *m = allowed(c, "fmi2SetupExperiment", MODE_INSTANTIATED);
    if (!m)
        return fmi2Error;
    m->start_time = startTime;
    m->has_stop = stopTimeDefined != fmi2False;
    m->stop_time = stopTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    fmu_instance *m = allowed(c, "fmi2EnterInitializationMode", MODE_INSTANTIATED);
    if (!m)
        return fmi2Error;
    m->mode = MODE_INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    fmu_instance *m = allowed(c, "fmi2ExitInitializationMode", MODE_INITIALIZATION);
    return m ? model_exit_initialization(m) : fmi2Error;
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    fmu_instance *m = allowed(c, "fmi2Terminate", MODE_STEP | MODE_INITIALIZATION);
    if (!m)
        return fmi2Error;
    m->mode = MODE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c)
{
    fmu_instance *m = allowed(c, "fmi2Reset", ANY_MODE);
    if (!m)
        return fmi2Error;
    model_reset(m);
    return fmi2OK;
}

/* ------------------------------------------------------------------ values */

#define GET_MODES (MODE_INITIALIZATION | MODE_STEP | MODE_TERMINATED | MODE_ERROR)
#define SET_MODES (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP)

#define TYPE_OF_REAL TYPE_REAL
#define TYPE_OF_INTEGER TYPE_INTEGER
#define TYPE_OF_BOOLEAN 2 /* no Boolean or String variables: any reference is refused */
#define TYPE_OF_STRING 3

/* the instance, when every value reference exists and is of the call's type (checked first: a bad
 * reference is named whatever the state) and the call is allowed in the instance's state */
static fmu_instance *checked(fmi2Component c, const char *call, int modes, const fmi2ValueReference vr[], size_t nvr,
                             int type)
{
    fmu_instance *m = (fmu_instance *)c;
    if (!m)
        return NULL;
    if (nvr && !vr) {
        fmu_log(m, fmi2Error, "%s: NULL value references for %zu values", call, nvr);
        return NULL;
    }
    if (model_check_type(m, vr, nvr, type, call) != fmi2OK)
        return NULL;
    return allowed(c, call, modes);
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    fmu_instance *m = checked(c, "fmi2GetReal", GET_MODES, vr, nvr, TYPE_OF_REAL);
    if (!m || null_arrays(m, "fmi2GetReal", nvr, vr, value))
        return fmi2Error;
    return model_get_real(m, vr, nvr, value);
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    fmu_instance *m = checked(c, "fmi2GetInteger", GET_MODES, vr, nvr, TYPE_OF_INTEGER);
    if (!m || null_arrays(m, "fmi2GetInteger", nvr, vr, value))
        return fmi2Error;
    return model_get_integer(m, vr, nvr, value);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    fmu_instance *m = checked(c, "fmi2GetBoolean", GET_MODES, vr, nvr, TYPE_OF_BOOLEAN);
    (void)value;
    if (!m) /* no Boolean variables: any is refused */
        return fmi2Error;
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    fmu_instance *m = checked(c, "fmi2GetString", GET_MODES, vr, nvr, TYPE_OF_STRING);
    (void)value;
    if (!m)
        return fmi2Error;
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    fmu_instance *m = checked(c, "fmi2SetReal", SET_MODES, vr, nvr, TYPE_OF_REAL);
    if (!m || null_arrays(m, "fmi2SetReal", nvr, vr, value))
        return fmi2Error;
    return model_set_real(m, vr, nvr, value);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[])
{
    fmu_instance *m = checked(c, "fmi2SetInteger", SET_MODES, vr, nvr, TYPE_OF_INTEGER);
    if (!m || null_arrays(m, "fmi2SetInteger", nvr, vr, value))
        return fmi2Error;
    return model_set_integer(m, vr, nvr, value);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[])
{
    fmu_instance *m = checked(c, "fmi2SetBoolean", SET_MODES, vr, nvr, TYPE_OF_BOOLEAN);
    (void)value;
    if (!m)
        return fmi2Error;
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[])
{
    fmu_instance *m = checked(c, "fmi2SetString", SET_MODES, vr, nvr, TYPE_OF_STRING);
    (void)value;
    if (!m)
        return fmi2Error;
    return fmi2OK;
}

/* ------------------------------------------------------------------ FMU state (model.c model_state_*) */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    fmu_instance *m = allowed(c, "fmi2GetFMUstate", ANY_MODE);
    return m && FMUstate ? model_state_get(m, "fmi2GetFMUstate", FMUstate) : fmi2Error;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    fmu_instance *m = allowed(c, "fmi2SetFMUstate", ANY_MODE);
    return m ? model_state_set(m, "fmi2SetFMUstate", FMUstate) : fmi2Error;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    (void)c;
    model_state_free(FMUstate);
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size)
{
    return allowed(c, "fmi2SerializedFMUstateSize", ANY_MODE) ? model_state_size(FMUstate, size) : fmi2Error;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size)
{
    fmu_instance *m = allowed(c, "fmi2SerializeFMUstate", ANY_MODE);
    return m ? model_state_serialize(m, "fmi2SerializeFMUstate", FMUstate, (unsigned char *)serializedState, size)
             : fmi2Error;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate)
{
    fmu_instance *m = allowed(c, "fmi2DeSerializeFMUstate", ANY_MODE);
    return m ? model_state_deserialize(m, "fmi2DeSerializeFMUstate", (const unsigned char *)serializedState, size,
                                       FMUstate)
             : fmi2Error;
}

/* ------------------------------------------------------------------ derivatives */

static fmi2Status derivative(fmi2Component c, const char *call, int meaning, const fmi2ValueReference vUnknown_ref[],
                             size_t nUnknown, const fmi2ValueReference vKnown_ref[], size_t nKnown,
                             const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    fmu_instance *m = allowed(c, call, MODE_STEP | MODE_INITIALIZATION); /* the model says why not in initialization */
    if (!m || null_arrays(m, call, nUnknown, vUnknown_ref, dvUnknown) || null_arrays(m, call, nKnown, vKnown_ref, dvKnown))
        return fmi2Error;
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

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    fmu_instance *m = allowed(c, "fmi2SetRealInputDerivatives", ANY_MODE);
    if (m)
        fmu_log(m, fmi2Error, "fmi2SetRealInputDerivatives: this FMU does not interpolate inputs "
                "(canInterpolateInputs=false): set the rates and accelerations as inputs (P.v, P.a, P.w, P.dw)");
    return fmi2Error;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    fmu_instance *m = allowed(c, "fmi2GetRealOutputDerivatives", ANY_MODE);
    if (m)
        fmu_log(m, fmi2Error, "fmi2GetRealOutputDerivatives: maxOutputDerivativeOrder is 0");
    return fmi2Error;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    fmu_instance *m = (fmu_instance *)c;
    if (m && m->mode == MODE_TERMINATED) {
        fmu_log(m, fmi2Error, "t = %.6g s: fmi2DoStep after fmi2Terminate (reset or free the instance)",
                currentCommunicationPoint);
        return fmi2Error;
    }
    if (m && m->mode == MODE_STEP && m->failure[0]) /* model_do_step names the failed initialization */
        return model_do_step(m, currentCommunicationPoint, communicationStepSize);
    m = allowed(c, "fmi2DoStep", MODE_STEP);
    return m ? model_do_step(m, currentCommunicationPoint, communicationStepSize) : fmi2Error;
}

fmi2Status fmi2CancelStep(fmi2Component c)
{
    fmu_instance *m = allowed(c, "fmi2CancelStep", ANY_MODE);
    if (m)
        fmu_log(m, fmi2Error, "fmi2CancelStep: doStep is synchronous (canRunAsynchronuously=false): nothing to cancel");
    return fmi2Error;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    (void)s;
    (void)value;
    fmu_instance *m = allowed(c, "fmi2GetStatus", ANY_MODE);
    if (m)
        fmu_log(m, fmi2Error, "fmi2GetStatus: doStep is synchronous: no pending status");
    return fmi2Error;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    fmu_instance *m = allowed(c, "fmi2GetRealStatus", MODE_STEP | MODE_TERMINATED | MODE_ERROR);
    if (!m || !value)
        return fmi2Error;
    if (s != fmi2LastSuccessfulTime || !m->body) {
        fmu_log(m, fmi2Error, "fmi2GetRealStatus: only fmi2LastSuccessfulTime is available, after initialization");
        return fmi2Error;
    }
    *value = model_time(m);
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    (void)s;
    (void)value;
    fmu_instance *m = allowed(c, "fmi2GetIntegerStatus", ANY_MODE);
    if (m)
        fmu_log(m, fmi2Error, "fmi2GetIntegerStatus: no integer status");
    return fmi2Error;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    (void)s;
    (void)value;
    fmu_instance *m = allowed(c, "fmi2GetBooleanStatus", ANY_MODE);
    if (m)
        fmu_log(m, fmi2Error, "fmi2GetBooleanStatus: no boolean status (doStep never terminates the simulation)");
    return fmi2Error;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    (void)s;
    (void)value;
    fmu_instance *m = allowed(c, "fmi2GetStringStatus", ANY_MODE);
    if (m)
        fmu_log(m, fmi2Error, "fmi2GetStringStatus: no string status");
    return fmi2Error;
}

/* ------------------------------------------------------------------ model exchange: not supported */

static fmi2Status no_model_exchange(fmi2Component c, const char *call)
{
    fmu_instance *m = (fmu_instance *)c;
    if (m)
        fmu_log(m, fmi2Error, "%s: this FMU supports co-simulation only", call);
    return fmi2Error;
}

fmi2Status fmi2EnterEventMode(fmi2Component c)
{
    return no_model_exchange(c, "fmi2EnterEventMode");
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info)
{
    (void)info;
    return no_model_exchange(c, "fmi2NewDiscreteStates");
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c)
{
    return no_model_exchange(c, "fmi2EnterContinuousTimeMode");
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    (void)enterEventMode;
    (void)terminateSimulation;
    return no_model_exchange(c, "fmi2CompletedIntegratorStep");
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time)
{
    (void)time;
    return no_model_exchange(c, "fmi2SetTime");
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx)
{
    (void)x;
    (void)nx;
    return no_model_exchange(c, "fmi2SetContinuousStates");
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx)
{
    (void)derivatives;
    (void)nx;
    return no_model_exchange(c, "fmi2GetDerivatives");
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni)
{
    (void)eventIndicators;
    (void)ni;
    return no_model_exchange(c, "fmi2GetEventIndicators");
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx)
{
    (void)x;
    (void)nx;
    return no_model_exchange(c, "fmi2GetContinuousStates");
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx)
{
    (void)x_nominal;
    (void)nx;
    return no_model_exchange(c, "fmi2GetNominalsOfContinuousStates");
}
