/* Native entry point of a body FMU on Linux: binaries/linux64/<modelIdentifier>.so.
 *
 * pythonfmu's binary (shipped next to this one as <modelIdentifier>.pythonfmu.so) leaves every
 * Py* symbol undefined: it works only in a process that already has libpython in its global
 * symbol scope (a Python host such as fmpy), and crashes any other host (PythonFMU issue #202).
 * This loader, compiled when the FMU is built, makes the FMU work in any FMI host:
 *
 *  1. On the first fmi2Instantiate, when the process has no Python (dlsym(RTLD_DEFAULT,
 *     "Py_IsInitialized") finds nothing), it loads libpython with RTLD_GLOBAL: the path in
 *     $FFRF_FMU_LIBPYTHON, else the one recorded at build time in resources/ffrf_libpython.txt.
 *     RTLD_GLOBAL matters: numpy's and scipy's extension modules resolve Py* symbols in the
 *     global scope. A process that already has Python keeps its own (one interpreter only).
 *  2. It loads pythonfmu's binary (RTLD_NODELETE: numpy cannot be initialized twice in one
 *     process, so the interpreter stays until the process exits) and forwards every fmi2 call.
 *  3. pythonfmu returns only OK, Discard or Fatal, and Fatal leaves its instance with released
 *     Python objects (the next call crashes). The slave never raises (slave_template.py); it logs
 *     failures at status Error. The loader gives each instance its own logger callback, records
 *     the worst status logged during a call and returns it when it is worse than the returned
 *     status: a call that logged an Error returns fmi2Error. After a Fatal the instance accepts
 *     no call but fmi2FreeInstance (which then leaks it rather than touching freed objects).
 *  4. Messages of status Warning and worse always reach the host's logger (FMI 2.0: debug
 *     logging switches only the debug messages); status-OK messages only with debug logging on.
 *     A NULL category from pythonfmu becomes logStatusXxx.
 *  5. The heap corruption at process exit (PythonFMU issue #228, "free(): corrupted unsorted
 *     chunks" after an fmpy run and in a C host) is pythonfmu's: its global
 *     `std::shared_ptr<PyState> pyState` (PythonFMU PR #213 keeps the interpreter alive until the
 *     library unloads) is destroyed by the exit handlers (__cxa_atexit), and
 *     afterwards its __attribute__((destructor)) onLibraryUnload() assigns nullptr to the
 *     destroyed shared_ptr, releasing the freed control block a second time (found with
 *     valgrind: "Invalid read ... in finalizePythonInterpreter ... block free'd by
 *     __run_exit_handlers"). An exit handler registered after pythonfmu's binary is loaded runs
 *     before that static destructor: it calls pythonfmu's own finalizePythonInterpreter(), which
 *     empties the shared_ptr in order (finalizing the interpreter when pythonfmu started it);
 *     the later destructor and onLibraryUnload then find an empty pointer. This library is linked
 *     with -z nodelete so that the handler's code is still there at exit.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <limits.h>
#include <pthread.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#define EXPORT __attribute__((visibility("default")))

/* glibc 2.34 moved dl* into libc with a new symbol version; bind the old one so that the loader
 * needs no newer glibc than pythonfmu's binary does (2.32) */
#if defined(__x86_64__)
__asm__(".symver dlopen,dlopen@GLIBC_2.2.5");
__asm__(".symver dlsym,dlsym@GLIBC_2.2.5");
__asm__(".symver dlerror,dlerror@GLIBC_2.2.5");
__asm__(".symver dladdr,dladdr@GLIBC_2.2.5");
#endif

#include "fmi2FunctionTypes.h" /* the standard's types (native/, compiled with -I there) */

typedef struct {
    fmi2Component real;            /* pythonfmu's instance */
    fmi2CallbackFunctions own;     /* passed to pythonfmu: logger = log_relay, environment = this */
    fmi2CallbackFunctions host;    /* the host's callbacks */
    char *name;
    int debug;                     /* the host's debug logging switch */
    int dead;                      /* a Fatal happened: only fmi2FreeInstance */
    fmi2Status worst;              /* worst status logged during the current call */
} Instance;

/* ------------------------------------------------------------------ the real library */
#define REAL_FUNCTIONS(X)                                                                           \
    X(fmi2Component, fmi2Instantiate, (fmi2String, fmi2Type, fmi2String, fmi2String,                \
                                       const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean))    \
    X(void, fmi2FreeInstance, (fmi2Component))                                                      \
    X(fmi2Status, fmi2SetDebugLogging, (fmi2Component, fmi2Boolean, size_t, const fmi2String[]))    \
    X(fmi2Status, fmi2SetupExperiment, (fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean, fmi2Real)) \
    X(fmi2Status, fmi2EnterInitializationMode, (fmi2Component))                                     \
    X(fmi2Status, fmi2ExitInitializationMode, (fmi2Component))                                      \
    X(fmi2Status, fmi2Terminate, (fmi2Component))                                                   \
    X(fmi2Status, fmi2Reset, (fmi2Component))                                                       \
    X(fmi2Status, fmi2GetReal, (fmi2Component, const fmi2ValueReference[], size_t, fmi2Real[]))     \
    X(fmi2Status, fmi2GetInteger, (fmi2Component, const fmi2ValueReference[], size_t, fmi2Integer[])) \
    X(fmi2Status, fmi2GetBoolean, (fmi2Component, const fmi2ValueReference[], size_t, fmi2Boolean[])) \
    X(fmi2Status, fmi2GetString, (fmi2Component, const fmi2ValueReference[], size_t, fmi2String[])) \
    X(fmi2Status, fmi2SetReal, (fmi2Component, const fmi2ValueReference[], size_t, const fmi2Real[])) \
    X(fmi2Status, fmi2SetInteger, (fmi2Component, const fmi2ValueReference[], size_t, const fmi2Integer[])) \
    X(fmi2Status, fmi2SetBoolean, (fmi2Component, const fmi2ValueReference[], size_t, const fmi2Boolean[])) \
    X(fmi2Status, fmi2SetString, (fmi2Component, const fmi2ValueReference[], size_t, const fmi2String[])) \
    X(fmi2Status, fmi2GetFMUstate, (fmi2Component, fmi2FMUstate *))                                 \
    X(fmi2Status, fmi2SetFMUstate, (fmi2Component, fmi2FMUstate))                                   \
    X(fmi2Status, fmi2FreeFMUstate, (fmi2Component, fmi2FMUstate *))                                \
    X(fmi2Status, fmi2SerializedFMUstateSize, (fmi2Component, fmi2FMUstate, size_t *))              \
    X(fmi2Status, fmi2SerializeFMUstate, (fmi2Component, fmi2FMUstate, fmi2Byte[], size_t))         \
    X(fmi2Status, fmi2DeSerializeFMUstate, (fmi2Component, const fmi2Byte[], size_t, fmi2FMUstate *)) \
    X(fmi2Status, fmi2SetRealInputDerivatives, (fmi2Component, const fmi2ValueReference[], size_t,  \
                                                const fmi2Integer[], const fmi2Real[]))             \
    X(fmi2Status, fmi2GetRealOutputDerivatives, (fmi2Component, const fmi2ValueReference[], size_t, \
                                                 const fmi2Integer[], fmi2Real[]))                  \
    X(fmi2Status, fmi2DoStep, (fmi2Component, fmi2Real, fmi2Real, fmi2Boolean))                     \
    X(fmi2Status, fmi2CancelStep, (fmi2Component))                                                  \
    X(fmi2Status, fmi2GetStatus, (fmi2Component, const fmi2StatusKind, fmi2Status *))               \
    X(fmi2Status, fmi2GetRealStatus, (fmi2Component, const fmi2StatusKind, fmi2Real *))             \
    X(fmi2Status, fmi2GetIntegerStatus, (fmi2Component, const fmi2StatusKind, fmi2Integer *))       \
    X(fmi2Status, fmi2GetBooleanStatus, (fmi2Component, const fmi2StatusKind, fmi2Boolean *))       \
    X(fmi2Status, fmi2GetStringStatus, (fmi2Component, const fmi2StatusKind, fmi2String *))

#define DECLARE(ret, name, args) static ret(*real_##name) args;
REAL_FUNCTIONS(DECLARE)

static void (*real_finalize)(void);
static void finalize_in_order(void) { real_finalize(); }

static pthread_mutex_t load_lock = PTHREAD_MUTEX_INITIALIZER;
static int loaded = 0;
static char load_error[4 * PATH_MAX];

static const char *status_category(fmi2Status s)
{
    static const char *names[] = {"logStatusOK", "logStatusWarning", "logStatusDiscard",
                                  "logStatusError", "logStatusFatal", "logStatusPending"};
    return (s >= fmi2OK && s <= fmi2Pending) ? names[s] : "logAll";
}

/* directory of this shared object (binaries/linux64), without the trailing slash */
static int own_directory(char *out, size_t size)
{
    Dl_info info;
    if (!dladdr((void *)&own_directory, &info) || !info.dli_fname) return 0;
    char resolved[PATH_MAX];
    if (!realpath(info.dli_fname, resolved)) return 0;
    char *slash = strrchr(resolved, '/');
    if (!slash) return 0;
    *slash = '\0';
    return snprintf(out, size, "%s", resolved) < (int)size;
}

static int load_real(void)
{
    char dir[PATH_MAX], path[3 * PATH_MAX];
    if (!own_directory(dir, sizeof dir)) {
        snprintf(load_error, sizeof load_error, "ffrf-fmu loader: cannot find its own directory");
        return 0;
    }
    if (!dlsym(RTLD_DEFAULT, "Py_IsInitialized")) {
        char libpython[PATH_MAX] = "";
        const char *env = getenv("FFRF_FMU_LIBPYTHON");
        if (env && *env) {
            snprintf(libpython, sizeof libpython, "%s", env);
        } else {
            snprintf(path, sizeof path, "%s/../../resources/ffrf_libpython.txt", dir);
            FILE *f = fopen(path, "r");
            if (f) {
                char home[PATH_MAX] = "";
                if (fgets(libpython, sizeof libpython, f)) libpython[strcspn(libpython, "\r\n")] = '\0';
                /* the second line: that Python's home (sys.base_prefix). Set as PYTHONHOME (unless the host
                 * set one), the embedded interpreter finds its standard library there, not in the prefix
                 * of whatever python3 comes first on PATH ("No module named 'math'" with Debian's
                 * python3.11 first on PATH and a pyenv 3.11 behind the FMU) */
                if (fgets(home, sizeof home, f)) home[strcspn(home, "\r\n")] = '\0';
                fclose(f);
                struct stat st;
                if (*home && !getenv("PYTHONHOME") && stat(home, &st) == 0) setenv("PYTHONHOME", home, 0);
            }
        }
        if (!*libpython) {
            snprintf(load_error, sizeof load_error,
                     "ffrf-fmu loader: this process has no Python and the FMU records no libpython: set "
                     "FFRF_FMU_LIBPYTHON to a libpython3.x.so.1.0 with numpy and scipy installed");
            return 0;
        }
        if (!dlopen(libpython, RTLD_NOW | RTLD_GLOBAL | RTLD_NODELETE)) {
            snprintf(load_error, sizeof load_error,
                     "ffrf-fmu loader: cannot load libpython (%s; set FFRF_FMU_LIBPYTHON to override): %s",
                     libpython, dlerror());
            return 0;
        }
    }
    const char *self = NULL;
    {
        Dl_info info;
        if (dladdr((void *)&own_directory, &info)) self = strrchr(info.dli_fname, '/');
    }
    char stem[PATH_MAX];
    snprintf(stem, sizeof stem, "%s", self ? self + 1 : "");
    char *dot = strrchr(stem, '.');
    if (dot) *dot = '\0';
    snprintf(path, sizeof path, "%s/%s.pythonfmu.so", dir, stem);
    void *real = dlopen(path, RTLD_NOW | RTLD_LOCAL | RTLD_NODELETE);
    if (!real) {
        snprintf(load_error, sizeof load_error, "ffrf-fmu loader: cannot load pythonfmu's binary: %s", dlerror());
        return 0;
    }
#define RESOLVE(ret, name, args)                                                                    \
    real_##name = (ret(*) args)dlsym(real, #name);                                                  \
    if (!real_##name) {                                                                             \
        snprintf(load_error, sizeof load_error, "ffrf-fmu loader: %s lacks %s", path, #name);       \
        return 0;                                                                                   \
    }
    REAL_FUNCTIONS(RESOLVE)
    real_finalize = (void (*)(void))dlsym(real, "finalizePythonInterpreter");
    if (real_finalize) atexit(finalize_in_order);
    return 1;
}

/* ------------------------------------------------------------------ logging */
static void log_relay(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                      fmi2String message, ...)
{
    Instance *inst = (Instance *)env;
    if (!inst) return;
    if (status > inst->worst && status <= fmi2Fatal) inst->worst = status;
    if (!inst->host.logger || (status == fmi2OK && !inst->debug)) return;
    /* the message is passed as an argument, never as a format */
    inst->host.logger(inst->host.componentEnvironment, name ? name : inst->name, status,
                      category ? category : status_category(status), "%s", message ? message : "");
}

static void say(Instance *inst, fmi2Status status, const char *fmt, const char *arg)
{
    if (inst && inst->host.logger) {
        char text[PATH_MAX + 1024];
        snprintf(text, sizeof text, fmt, arg);
        inst->host.logger(inst->host.componentEnvironment, inst->name, status, status_category(status), "%s", text);
    }
}

/* ------------------------------------------------------------------ forwarding */
static fmi2Status finish(Instance *inst, fmi2Status s)
{
    if (inst->worst > s && inst->worst <= fmi2Fatal) s = inst->worst;
    if (s == fmi2Fatal) inst->dead = 1;
    return s;
}

#define ENTER(c, fname)                                                                              \
    Instance *inst = (Instance *)(c);                                                               \
    if (!inst) return fmi2Error;                                                                    \
    if (inst->dead) {                                                                               \
        say(inst, fmi2Error, "%s: refused: this instance had a fatal error earlier; only fmi2FreeInstance " \
            "is allowed", fname);                                                                   \
        return fmi2Error;                                                                           \
    }                                                                                               \
    inst->worst = fmi2OK;

#define FORWARD(name, params, args)                                                                 \
    EXPORT fmi2Status name params                                                                   \
    {                                                                                               \
        ENTER(c, #name)                                                                             \
        return finish(inst, real_##name args);                                                      \
    }

EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

/* The local folder of a resource location (file:///abs, file:/abs, file://localhost/abs, a plain absolute path;
 * percent-escapes decoded) into out as "file://" + path, the one form pythonfmu reads; 0, or -1 with why in
 * err (another host or scheme, a relative or badly escaped URI, a folder that is not there): pythonfmu
 * crashed the host on file:/abs and on a missing folder. */
static int resource_uri(const char *uri, char *out, size_t size, char *err, size_t err_size)
{
    if (!uri || !*uri) {
        snprintf(err, err_size, "no resource location given: the FMU needs its resources folder");
        return -1;
    }
    const char *p = uri;
    if (strncmp(p, "file:", 5) == 0) {
        p += 5;
        if (strncmp(p, "//", 2) == 0) {
            p += 2;
            if (strncmp(p, "localhost/", 10) == 0) p += 9;
            else if (*p != '/') {
                snprintf(err, err_size, "resource location %.300s names another host: only local files can be read", uri);
                return -1;
            }
        }
    } else if (strstr(p, "://")) {
        snprintf(err, err_size, "resource location %.300s: only file URIs are supported", uri);
        return -1;
    }
    if (*p != '/') {
        snprintf(err, err_size, "resource location %.300s is not an absolute file URI (file:///path)", uri);
        return -1;
    }
    char path[PATH_MAX];
    size_t k = 0;
    for (; *p && k + 1 < sizeof path; p++) {
        char c = *p;
        if (c == '%') {
            int hi, lo;
            if (sscanf(p + 1, "%1x%1x", &hi, &lo) != 2 || !(hi | lo)) {
                snprintf(err, err_size, "resource location %.300s has a bad percent-escape", uri);
                return -1;
            }
            c = (char)(16 * hi + lo);
            p += 2;
        }
        path[k++] = c;
    }
    path[k] = '\0';
    struct stat st;
    if (stat(path, &st) != 0 || !S_ISDIR(st.st_mode)) {
        snprintf(err, err_size, "resources folder %.300s (from %.300s) is missing or not a folder", path, uri);
        return -1;
    }
    if (snprintf(out, size, "file://%s", path) >= (int)size) {
        snprintf(err, err_size, "resource location %.300s is too long", uri);
        return -1;
    }
    return 0;
}

EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                     fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                                     fmi2Boolean visible, fmi2Boolean loggingOn)
{
    Instance *inst = calloc(1, sizeof *inst);
    if (!inst) return NULL;
    if (functions) inst->host = *functions;
    inst->name = strdup(instanceName ? instanceName : "");
    inst->debug = loggingOn ? 1 : 0;
    pthread_mutex_lock(&load_lock);
    if (!loaded) loaded = load_real() ? 1 : -1;
    int ok = loaded == 1;
    pthread_mutex_unlock(&load_lock);
    if (!ok) {
        say(inst, fmi2Fatal, "%s", load_error);
        free(inst->name);
        free(inst);
        return NULL;
    }
    char uri[PATH_MAX + 16], why[1024];
    if (resource_uri(fmuResourceLocation, uri, sizeof uri, why, sizeof why)) {
        say(inst, fmi2Error, "fmi2Instantiate: %s", why);
        free(inst->name);
        free(inst);
        return NULL;
    }
    inst->own = inst->host;
    inst->own.logger = log_relay;
    inst->own.componentEnvironment = inst;
    /* pythonfmu always logs to the relay, which applies the host's switch */
    inst->real = real_fmi2Instantiate(instanceName, fmuType, fmuGUID, uri, &inst->own, visible,
                                      1);
    if (!inst->real) {
        free(inst->name);
        free(inst);
        return NULL;
    }
    return inst;
}

EXPORT void fmi2FreeInstance(fmi2Component c)
{
    Instance *inst = (Instance *)c;
    if (!inst) return;
    if (!inst->dead) real_fmi2FreeInstance(inst->real);
    free(inst->name);
    free(inst);
}

EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                                      const fmi2String categories[])
{
    ENTER(c, "fmi2SetDebugLogging")
    (void)nCategories;
    (void)categories;
    inst->debug = loggingOn ? 1 : 0;
    return fmi2OK;
}

FORWARD(fmi2SetupExperiment, (fmi2Component c, fmi2Boolean td, fmi2Real tol, fmi2Real t0, fmi2Boolean sd, fmi2Real t1),
        (inst->real, td, tol, t0, sd, t1))
FORWARD(fmi2EnterInitializationMode, (fmi2Component c), (inst->real))
FORWARD(fmi2ExitInitializationMode, (fmi2Component c), (inst->real))
FORWARD(fmi2Terminate, (fmi2Component c), (inst->real))
FORWARD(fmi2Reset, (fmi2Component c), (inst->real))
FORWARD(fmi2GetReal, (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]), (inst->real, vr, n, v))
FORWARD(fmi2GetInteger, (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]),
        (inst->real, vr, n, v))
FORWARD(fmi2GetBoolean, (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]),
        (inst->real, vr, n, v))
FORWARD(fmi2GetString, (fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]),
        (inst->real, vr, n, v))
FORWARD(fmi2SetReal, (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]),
        (inst->real, vr, n, v))
FORWARD(fmi2SetInteger, (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]),
        (inst->real, vr, n, v))
FORWARD(fmi2SetBoolean, (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]),
        (inst->real, vr, n, v))
FORWARD(fmi2SetString, (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]),
        (inst->real, vr, n, v))
FORWARD(fmi2GetFMUstate, (fmi2Component c, fmi2FMUstate *s), (inst->real, s))
FORWARD(fmi2SetFMUstate, (fmi2Component c, fmi2FMUstate s), (inst->real, s))
FORWARD(fmi2FreeFMUstate, (fmi2Component c, fmi2FMUstate *s), (inst->real, s))
FORWARD(fmi2SerializedFMUstateSize, (fmi2Component c, fmi2FMUstate s, size_t *n), (inst->real, s, n))
FORWARD(fmi2SerializeFMUstate, (fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n), (inst->real, s, b, n))
FORWARD(fmi2DeSerializeFMUstate, (fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s),
        (inst->real, b, n, s))
/* pythonfmu has no fmi2GetDirectionalDerivative. The request goes to this instance's own Python slave
 * through pythonfmu's fmi2SetReal and fmi2GetReal on the same component, on value references offset
 * into a range no variable uses (fmu/variables.py DERIVATIVE_CHANNEL, passed by the builder as
 * -DFFRF_DERIVATIVE_SEED/_OUTPUT/_POINT): first the seeds at SEED + known, then the derivatives read at
 * POINT + unknown (fmi2GetDirectionalDerivative: FMI's partial derivatives at the communication point) or
 * OUTPUT + unknown (ffrf2GetStepDerivative, not an FMI function: those of the last communication step;
 * docs/fmu.md). Nothing is kept outside the instance, so two instances in one process never see each
 * other's request. */
#if !defined(FFRF_DERIVATIVE_SEED) || !defined(FFRF_DERIVATIVE_OUTPUT) || !defined(FFRF_DERIVATIVE_POINT)
#error "compile with -DFFRF_DERIVATIVE_SEED=... -DFFRF_DERIVATIVE_OUTPUT=... -DFFRF_DERIVATIVE_POINT=... (ffrf_fmu/fmu/builder.py does)"
#endif
static fmi2Status derivative(fmi2Component c, const char *call, fmi2ValueReference channel,
                             const fmi2ValueReference vUnknown[], size_t nUnknown, const fmi2ValueReference vKnown[],
                             size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    ENTER(c, call)
    char text[160];
    if (nUnknown == 0) return fmi2OK;
    if (!vUnknown || !dvUnknown || (nKnown && (!vKnown || !dvKnown))) {
        snprintf(text, sizeof text, "%s: a NULL array", call);
        say(inst, fmi2Error, "%s", text);
        return fmi2Error;
    }
    if (nKnown == 0) {
        for (size_t i = 0; i < nUnknown; i++) dvUnknown[i] = 0.0;
        return fmi2OK;
    }
    for (size_t i = 0; i < nKnown + nUnknown; i++) {
        fmi2ValueReference vr = i < nKnown ? vKnown[i] : vUnknown[i - nKnown];
        if (vr >= FFRF_DERIVATIVE_SEED) {
            snprintf(text, sizeof text, "%s: unknown value reference %u", call, vr);
            say(inst, fmi2Error, "%s", text);
            return fmi2Error;
        }
    }
    fmi2ValueReference *known = malloc(nKnown * sizeof *known), *unknown = malloc(nUnknown * sizeof *unknown);
    fmi2Status s = fmi2Error;
    if (known && unknown) {
        for (size_t i = 0; i < nKnown; i++) known[i] = FFRF_DERIVATIVE_SEED + vKnown[i];
        for (size_t i = 0; i < nUnknown; i++) unknown[i] = channel + vUnknown[i];
        s = real_fmi2SetReal(inst->real, known, nKnown, dvKnown);
        if (s == fmi2OK && inst->worst < fmi2Error) s = real_fmi2GetReal(inst->real, unknown, nUnknown, dvUnknown);
    } else {
        snprintf(text, sizeof text, "%s: out of memory", call);
        say(inst, fmi2Error, "%s", text);
    }
    free(known);
    free(unknown);
    return finish(inst, s);
}

EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown[], size_t nUnknown,
                                               const fmi2ValueReference vKnown[], size_t nKnown,
                                               const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    return derivative(c, "fmi2GetDirectionalDerivative", FFRF_DERIVATIVE_POINT, vUnknown, nUnknown, vKnown, nKnown,
                      dvKnown, dvUnknown);
}

EXPORT fmi2Status ffrf2GetStepDerivative(fmi2Component c, const fmi2ValueReference vUnknown[], size_t nUnknown,
                                         const fmi2ValueReference vKnown[], size_t nKnown, const fmi2Real dvKnown[],
                                         fmi2Real dvUnknown[])
{
    return derivative(c, "ffrf2GetStepDerivative", FFRF_DERIVATIVE_OUTPUT, vUnknown, nUnknown, vKnown, nKnown, dvKnown,
                      dvUnknown);
}
FORWARD(fmi2SetRealInputDerivatives,
        (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer order[], const fmi2Real v[]),
        (inst->real, vr, n, order, v))
FORWARD(fmi2GetRealOutputDerivatives,
        (fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer order[], fmi2Real v[]),
        (inst->real, vr, n, order, v))
FORWARD(fmi2DoStep, (fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean keep), (inst->real, t, h, keep))
FORWARD(fmi2CancelStep, (fmi2Component c), (inst->real))
FORWARD(fmi2GetStatus, (fmi2Component c, const fmi2StatusKind k, fmi2Status *v), (inst->real, k, v))
FORWARD(fmi2GetRealStatus, (fmi2Component c, const fmi2StatusKind k, fmi2Real *v), (inst->real, k, v))
FORWARD(fmi2GetIntegerStatus, (fmi2Component c, const fmi2StatusKind k, fmi2Integer *v), (inst->real, k, v))
FORWARD(fmi2GetBooleanStatus, (fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v), (inst->real, k, v))
FORWARD(fmi2GetStringStatus, (fmi2Component c, const fmi2StatusKind k, fmi2String *v), (inst->real, k, v))
