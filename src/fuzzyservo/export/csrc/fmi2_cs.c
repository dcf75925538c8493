/* Message buffer size and phases of an instance, for the model code below. */
#include <float.h>

#define FSM_MSG 320

enum { FSM_INSTANTIATED, FSM_INIT, FSM_STEP, FSM_TERMINATED, FSM_ERROR };

/* @MODEL@ */

/*
 * FMI 2.0 co-simulation wrapper of one fuzzyservo model (a controller or the servo).
 *
 * Pasted after the model's code by fuzzyservo's FMU builder. The model provides:
 *
 *   #define FSM_GUID "..."             the GUID of modelDescription.xml
 *   #define FSM_N_VARS n               Real value references 0 .. n-1
 *   struct fsm_model { ... };          all of the model's data (no pointers: it is copied
 *                                      as the FMU state)
 *   static void fsm_defaults(struct fsm_model *m);                 start values
 *   static int  fsm_set(struct fsm_model *m, unsigned vr, double v, int phase, char *msg);
 *   static int  fsm_get(const struct fsm_model *m, unsigned vr, double *v);
 *   static int  fsm_initialize(struct fsm_model *m, double t0, char *msg);
 *   static int  fsm_do_step(struct fsm_model *m, double t, double h, char *msg);
 *   static double fsm_elapsed(const struct fsm_model *m);  time since t0 as the model
 *                                      counts it (its samples, not a master's sum of t + h)
 *   #define FSM_TS ts                  the sample time [s] (steps start where the last ended,
 *                                      within fsm_time_tol)
 *
 * Each returns 0 on success; otherwise it writes a one-line reason into msg (FSM_MSG bytes)
 * and the wrapper logs it and returns fmi2Error. Phases: 0 instantiated, 1 initialisation
 * mode, 2 step mode, 3 terminated, 4 error. The part above the line @MODEL@ goes before the
 * model's code.
 *
 * Memory comes from the environment's allocateMemory/freeMemory, as FMI requires; the
 * model code itself allocates nothing.
 */


typedef struct {
    struct fsm_model m;
    double time;
    int phase;
} fsm_snapshot;

typedef struct {
    fsm_snapshot now;
    fmi2CallbackFunctions cb;
    char *name;
    int logging;
    double t0;
    int stop_defined; /* fmi2SetupExperiment's stopTime, which no step may pass */
    double stop;
} fsm_instance;

/* How far apart two times a master computed differently may be and still be one: 1e-6 ts
 * and the rounding of |t| (a master's t0 + n h against its t + h). */
static double fsm_time_tol(double t)
{
    return 1e-6 * FSM_TS + 8.0 * DBL_EPSILON * fabs(t);
}

static void fsm_log(fsm_instance *inst, fmi2Status status, const char *category,
                    const char *msg)
{
    if (inst->cb.logger == NULL) {
        return;
    }
    if (status == fmi2OK && !inst->logging) {
        return;
    }
    inst->cb.logger(inst->cb.componentEnvironment, inst->name, status, category, "%s", msg);
}

static fmi2Status fsm_fail(fsm_instance *inst, const char *msg)
{
    fsm_log(inst, fmi2Error, "logStatusError", msg);
    inst->now.phase = FSM_ERROR; /* FMI 2.0: after fmi2Error only reset or free */
    return fmi2Error;
}

static int fsm_phase_ok(fsm_instance *inst, const char *fn, unsigned allowed)
{
    char msg[FSM_MSG];
    if (allowed & (1u << inst->now.phase)) {
        return 1;
    }
    sprintf(msg, "%.40s is not allowed in this state (%d)", fn, inst->now.phase);
    fsm_fail(inst, msg);
    return 0;
}

FMI2_Export const char *fmi2GetTypesPlatform(void)
{
    return fmi2TypesPlatform;
}

FMI2_Export const char *fmi2GetVersion(void)
{
    return fmi2Version;
}

FMI2_Export fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn,
                                           size_t nCategories, const fmi2String categories[])
{
    fsm_instance *inst = (fsm_instance *)c;
    (void)nCategories;
    (void)categories;
    if (inst == NULL) {
        return fmi2Error;
    }
    inst->logging = loggingOn != fmi2False;
    return fmi2OK;
}

FMI2_Export fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType,
                                          fmi2String fmuGUID, fmi2String fmuResourceLocation,
                                          const fmi2CallbackFunctions *functions,
                                          fmi2Boolean visible, fmi2Boolean loggingOn)
{
    fsm_instance *inst;
    size_t n;
    (void)fmuResourceLocation;
    (void)visible;
    if (functions == NULL || functions->allocateMemory == NULL
        || functions->freeMemory == NULL) {
        return NULL;
    }
    if (instanceName == NULL) {
        instanceName = "";
    }
    if (fmuType != fmi2CoSimulation || fmuGUID == NULL || strcmp(fmuGUID, FSM_GUID) != 0) {
        if (functions->logger != NULL) {
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error,
                              "logStatusError", fmuType != fmi2CoSimulation
                              ? "this FMU is for co-simulation only"
                              : "GUID does not match this FMU's modelDescription.xml");
        }
        return NULL;
    }
    inst = (fsm_instance *)functions->allocateMemory(1, sizeof(fsm_instance));
    if (inst == NULL) {
        return NULL;
    }
    n = strlen(instanceName) + 1;
    inst->name = (char *)functions->allocateMemory(n, 1);
    if (inst->name == NULL) {
        functions->freeMemory(inst);
        return NULL;
    }
    memcpy(inst->name, instanceName, n);
    inst->cb = *functions;
    inst->logging = loggingOn != fmi2False;
    inst->t0 = 0.0;
    inst->stop_defined = 0;
    inst->stop = 0.0;
    inst->now.time = 0.0;
    inst->now.phase = FSM_INSTANTIATED;
    fsm_defaults(&inst->now.m);
    return inst;
}

FMI2_Export void fmi2FreeInstance(fmi2Component c)
{
    fsm_instance *inst = (fsm_instance *)c;
    fmi2CallbackFreeMemory release;
    if (inst == NULL) {
        return;
    }
    release = inst->cb.freeMemory;
    release(inst->name);
    release(inst);
}

FMI2_Export fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                                           fmi2Real tolerance, fmi2Real startTime,
                                           fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    fsm_instance *inst = (fsm_instance *)c;
    char msg[FSM_MSG];
    (void)toleranceDefined;
    (void)tolerance;
    if (inst == NULL || !fsm_phase_ok(inst, "fmi2SetupExperiment", 1u << FSM_INSTANTIATED)) {
        return fmi2Error;
    }
    if (!isfinite(startTime) || (stopTimeDefined && !(stopTime >= startTime
                                                       && stopTime <= DBL_MAX))) {
        sprintf(msg, "fmi2SetupExperiment: the start time (%g s) must be finite and a stop "
                "time (%g s) finite and >= it", startTime, stopTime);
        return fsm_fail(inst, msg);
    }
    inst->t0 = startTime;
    inst->stop_defined = stopTimeDefined != fmi2False;
    inst->stop = stopTime;
    inst->now.time = startTime;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    fsm_instance *inst = (fsm_instance *)c;
    if (inst == NULL
        || !fsm_phase_ok(inst, "fmi2EnterInitializationMode", 1u << FSM_INSTANTIATED)) {
        return fmi2Error;
    }
    inst->now.phase = FSM_INIT;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    fsm_instance *inst = (fsm_instance *)c;
    char msg[FSM_MSG];
    if (inst == NULL || !fsm_phase_ok(inst, "fmi2ExitInitializationMode", 1u << FSM_INIT)) {
        return fmi2Error;
    }
    msg[0] = '\0';
    if (fsm_initialize(&inst->now.m, inst->t0, msg) != 0) {
        inst->now.phase = FSM_ERROR;
        return fsm_fail(inst, msg);
    }
    inst->now.phase = FSM_STEP;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2Terminate(fmi2Component c)
{
    fsm_instance *inst = (fsm_instance *)c;
    if (inst == NULL || !fsm_phase_ok(inst, "fmi2Terminate", 1u << FSM_STEP)) {
        return fmi2Error;
    }
    inst->now.phase = FSM_TERMINATED;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2Reset(fmi2Component c)
{
    fsm_instance *inst = (fsm_instance *)c;
    if (inst == NULL) {
        return fmi2Error;
    }
    inst->t0 = 0.0;
    inst->stop_defined = 0;
    inst->stop = 0.0;
    inst->now.time = 0.0;
    inst->now.phase = FSM_INSTANTIATED;
    fsm_defaults(&inst->now.m);
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                   fmi2Real value[])
{
    fsm_instance *inst = (fsm_instance *)c;
    size_t i;
    char msg[FSM_MSG];
    if (inst == NULL || !fsm_phase_ok(inst, "fmi2GetReal", (1u << FSM_INIT) | (1u << FSM_STEP)
                                      | (1u << FSM_TERMINATED) | (1u << FSM_ERROR))) {
        return fmi2Error;
    }
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        return fsm_fail(inst, "fmi2GetReal: NULL array");
    }
    for (i = 0; i < nvr; i++) {
        if (vr[i] >= FSM_N_VARS || fsm_get(&inst->now.m, vr[i], &value[i]) != 0) {
            sprintf(msg, "fmi2GetReal: no Real variable has value reference %u",
                    (unsigned)vr[i]);
            return fsm_fail(inst, msg);
        }
    }
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                   const fmi2Real value[])
{
    fsm_instance *inst = (fsm_instance *)c;
    size_t i;
    char msg[FSM_MSG];
    if (inst == NULL || !fsm_phase_ok(inst, "fmi2SetReal", (1u << FSM_INSTANTIATED)
                                      | (1u << FSM_INIT) | (1u << FSM_STEP))) {
        return fmi2Error;
    }
    if (nvr > 0 && (vr == NULL || value == NULL)) {
        return fsm_fail(inst, "fmi2SetReal: NULL array");
    }
    for (i = 0; i < nvr; i++) {
        msg[0] = '\0';
        if (vr[i] >= FSM_N_VARS) {
            sprintf(msg, "fmi2SetReal: no Real variable has value reference %u",
                    (unsigned)vr[i]);
            return fsm_fail(inst, msg);
        }
        if (fsm_set(&inst->now.m, vr[i], value[i], inst->now.phase, msg) != 0) {
            return fsm_fail(inst, msg);
        }
    }
    return fmi2OK;
}

static fmi2Status fsm_no_vars(fmi2Component c, size_t nvr, const char *fn)
{
    fsm_instance *inst = (fsm_instance *)c;
    char msg[FSM_MSG];
    if (inst == NULL) {
        return fmi2Error;
    }
    if (nvr == 0) {
        return fmi2OK;
    }
    sprintf(msg, "%.40s: this FMU has Real variables only", fn);
    return fsm_fail(inst, msg);
}

FMI2_Export fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[],
                                      size_t nvr, fmi2Integer value[])
{
    (void)vr;
    (void)value;
    return fsm_no_vars(c, nvr, "fmi2GetInteger");
}

FMI2_Export fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[],
                                      size_t nvr, fmi2Boolean value[])
{
    (void)vr;
    (void)value;
    return fsm_no_vars(c, nvr, "fmi2GetBoolean");
}

FMI2_Export fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[],
                                     size_t nvr, fmi2String value[])
{
    (void)vr;
    (void)value;
    return fsm_no_vars(c, nvr, "fmi2GetString");
}

FMI2_Export fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[],
                                      size_t nvr, const fmi2Integer value[])
{
    (void)vr;
    (void)value;
    return fsm_no_vars(c, nvr, "fmi2SetInteger");
}

FMI2_Export fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[],
                                      size_t nvr, const fmi2Boolean value[])
{
    (void)vr;
    (void)value;
    return fsm_no_vars(c, nvr, "fmi2SetBoolean");
}

FMI2_Export fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[],
                                     size_t nvr, const fmi2String value[])
{
    (void)vr;
    (void)value;
    return fsm_no_vars(c, nvr, "fmi2SetString");
}

FMI2_Export fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    fsm_instance *inst = (fsm_instance *)c;
    fsm_snapshot *snap;
    if (inst == NULL || FMUstate == NULL) {
        return fmi2Error;
    }
    snap = (fsm_snapshot *)*FMUstate;
    if (snap == NULL) {
        snap = (fsm_snapshot *)inst->cb.allocateMemory(1, sizeof(fsm_snapshot));
        if (snap == NULL) {
            return fsm_fail(inst, "fmi2GetFMUstate: out of memory");
        }
    }
    *snap = inst->now;
    *FMUstate = snap;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    fsm_instance *inst = (fsm_instance *)c;
    if (inst == NULL || FMUstate == NULL) {
        return fmi2Error;
    }
    inst->now = *(const fsm_snapshot *)FMUstate;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    fsm_instance *inst = (fsm_instance *)c;
    if (inst == NULL || FMUstate == NULL) {
        return fmi2Error;
    }
    if (*FMUstate != NULL) {
        inst->cb.freeMemory(*FMUstate);
        *FMUstate = NULL;
    }
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate,
                                                  size_t *size)
{
    (void)FMUstate;
    if (c == NULL || size == NULL) {
        return fmi2Error;
    }
    *size = sizeof(fsm_snapshot) + sizeof(FSM_GUID);
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate,
                                             fmi2Byte serializedState[], size_t size)
{
    fsm_instance *inst = (fsm_instance *)c;
    if (inst == NULL || FMUstate == NULL || serializedState == NULL) {
        return fmi2Error;
    }
    if (size < sizeof(fsm_snapshot) + sizeof(FSM_GUID)) {
        return fsm_fail(inst, "fmi2SerializeFMUstate: buffer too small");
    }
    memcpy(serializedState, FSM_GUID, sizeof(FSM_GUID));
    memcpy(serializedState + sizeof(FSM_GUID), FMUstate, sizeof(fsm_snapshot));
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2DeSerializeFMUstate(fmi2Component c,
                                               const fmi2Byte serializedState[], size_t size,
                                               fmi2FMUstate *FMUstate)
{
    fsm_instance *inst = (fsm_instance *)c;
    fsm_snapshot *snap, check;
    if (inst == NULL || serializedState == NULL || FMUstate == NULL) {
        return fmi2Error;
    }
    if (size != sizeof(fsm_snapshot) + sizeof(FSM_GUID)
        || memcmp(serializedState, FSM_GUID, sizeof(FSM_GUID)) != 0) {
        return fsm_fail(inst, "fmi2DeSerializeFMUstate: not a state of this FMU");
    }
    memcpy(&check, serializedState + sizeof(FSM_GUID), sizeof(fsm_snapshot));
    if (check.phase < FSM_INSTANTIATED || check.phase > FSM_ERROR || !isfinite(check.time)) {
        return fsm_fail(inst, "fmi2DeSerializeFMUstate: not a state of this FMU");
    }
    snap = (fsm_snapshot *)*FMUstate;
    if (snap == NULL) {
        snap = (fsm_snapshot *)inst->cb.allocateMemory(1, sizeof(fsm_snapshot));
        if (snap == NULL) {
            return fsm_fail(inst, "fmi2DeSerializeFMUstate: out of memory");
        }
    }
    *snap = check;
    *FMUstate = snap;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetDirectionalDerivative(
    fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
    const fmi2ValueReference vKnown_ref[], size_t nKnown, const fmi2Real dvKnown[],
    fmi2Real dvUnknown[])
{
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    if (c == NULL) {
        return fmi2Error;
    }
    return fsm_fail((fsm_instance *)c, "fmi2GetDirectionalDerivative is not provided");
}

FMI2_Export fmi2Status fmi2SetRealInputDerivatives(fmi2Component c,
                                                   const fmi2ValueReference vr[], size_t nvr,
                                                   const fmi2Integer order[],
                                                   const fmi2Real value[])
{
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    if (c == NULL) {
        return fmi2Error;
    }
    return fsm_fail((fsm_instance *)c, "input derivatives are not used: inputs are sampled");
}

FMI2_Export fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c,
                                                    const fmi2ValueReference vr[], size_t nvr,
                                                    const fmi2Integer order[],
                                                    fmi2Real value[])
{
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    if (c == NULL) {
        return fmi2Error;
    }
    return fsm_fail((fsm_instance *)c, "output derivatives are not provided");
}

FMI2_Export fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                                  fmi2Real communicationStepSize,
                                  fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    fsm_instance *inst = (fsm_instance *)c;
    char msg[FSM_MSG];
    double end, counted;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (inst == NULL || !fsm_phase_ok(inst, "fmi2DoStep", 1u << FSM_STEP)) {
        return fmi2Error;
    }
    if (!isfinite(currentCommunicationPoint) || !isfinite(communicationStepSize)
        || !(communicationStepSize >= 0.0)) {
        sprintf(msg, "fmi2DoStep: the time (%g s) and the step (%g s) must be finite, the "
                "step >= 0", currentCommunicationPoint, communicationStepSize);
        return fsm_fail(inst, msg);
    }
    if (fabs(currentCommunicationPoint - inst->now.time) > fsm_time_tol(inst->now.time)) {
        sprintf(msg, "fmi2DoStep: a step must start where the last one ended, at t = %.17g s, "
                "not at %.17g s", inst->now.time, currentCommunicationPoint);
        return fsm_fail(inst, msg);
    }
    /* FMI 2.0: past a defined stop time, fmi2Error. The end of the step is the earlier of
     * the master's t + h and the model's count of samples (either may carry the master's
     * rounding), within fsm_time_tol. */
    end = currentCommunicationPoint + communicationStepSize;
    counted = inst->t0 + fsm_elapsed(&inst->now.m) + communicationStepSize;
    if (counted < end) {
        end = counted;
    }
    if (inst->stop_defined && end > inst->stop + fsm_time_tol(inst->stop)) {
        sprintf(msg, "fmi2DoStep: the step from t = %.17g s to %.17g s passes the stop time "
                "%.17g s given to fmi2SetupExperiment", currentCommunicationPoint,
                currentCommunicationPoint + communicationStepSize, inst->stop);
        return fsm_fail(inst, msg);
    }
    msg[0] = '\0';
    if (fsm_do_step(&inst->now.m, currentCommunicationPoint, communicationStepSize, msg)
        != 0) {
        inst->now.phase = FSM_ERROR;
        return fsm_fail(inst, msg);
    }
    inst->now.time = currentCommunicationPoint + communicationStepSize;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2CancelStep(fmi2Component c)
{
    if (c == NULL) {
        return fmi2Error;
    }
    return fsm_fail((fsm_instance *)c, "fmi2CancelStep: steps are never asynchronous");
}

FMI2_Export fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s,
                                     fmi2Status *value)
{
    (void)s;
    if (c == NULL || value == NULL) {
        return fmi2Error;
    }
    return fmi2Discard;
}

FMI2_Export fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s,
                                         fmi2Real *value)
{
    fsm_instance *inst = (fsm_instance *)c;
    if (inst == NULL || value == NULL) {
        return fmi2Error;
    }
    if (s == fmi2LastSuccessfulTime) {
        *value = inst->now.time;
        return fmi2OK;
    }
    return fmi2Discard;
}

FMI2_Export fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s,
                                            fmi2Integer *value)
{
    (void)s;
    if (c == NULL || value == NULL) {
        return fmi2Error;
    }
    return fmi2Discard;
}

FMI2_Export fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s,
                                            fmi2Boolean *value)
{
    (void)s;
    if (c == NULL || value == NULL) {
        return fmi2Error;
    }
    return fmi2Discard;
}

FMI2_Export fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s,
                                           fmi2String *value)
{
    (void)s;
    if (c == NULL || value == NULL) {
        return fmi2Error;
    }
    return fmi2Discard;
}
