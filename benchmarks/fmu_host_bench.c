/* The native FMU in a plain C host against the C runtime it wraps, same inputs, same machine, one process
 * (benchmarks/fmu_overhead.py compiles and runs it).
 *
 *   fmu_host_bench FMU_BINARY RESOURCE_URI GUID RUNTIME_LIBRARY IMAGE TABLE STEPS H REPEAT INTERNAL [STEP_LOG ITER_VR]
 *
 * INTERNAL: internal steps per communication step (H / solver.step), as the FMU takes them.
 * TABLE (binary, little-endian doubles): n_in, n_point, n_out, then n_in value references, n_out value
 * references (as doubles), then per communication step k = 0..STEPS: the n_in input values at t_k and the
 * n_point point values (runtime/input_rule.py, one row per port) the FMU's input rule makes of them.
 *   fmu      fmi2SetReal(inputs at t_k), fmi2DoStep(t_k, H), fmi2GetReal(outputs): the FMU as a master runs it
 *   runtime  the runtime library's body (from IMAGE, started from the FMU's initial state): point values at
 *            t_k, ffrf_body_advance(EXTRAPOLATED, H / h steps), ffrf_body_record: the same numbers without the FMI layer
 * Prints CPU seconds (CLOCK_PROCESS_CPUTIME_ID) of each loop (best of REPEAT), the wall time of instantiate +
 * initialize + the first doStep, and whether the last outputs of both are equal.
 * With STEP_LOG (benchmarks/realtime.py, the real-time datasheet): the FMU loop only, once, every fmi2DoStep timed
 * alone (wall: CLOCK_MONOTONIC, CPU: CLOCK_THREAD_CPUTIME_ID, read just before and after the call) and the Integer
 * output ITER_VR (solver.newton_iterations) read after it; STEP_LOG gets STEPS rows of three little-endian doubles
 * (wall s, CPU s, iterations). A doStep that does not return fmi2OK ends the run with its status as exit code 20 +
 * status, the rows so far written. */
#define _POSIX_C_SOURCE 200809L
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "../tests/host_loader.h" /* open_library, sym */

typedef void *fmi2Component;
typedef unsigned int vr_t;
typedef void (*Logger)(void *, const char *, int, const char *, const char *, ...);
typedef struct {
    Logger logger;
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void *stepFinished;
    void *componentEnvironment;
} Callbacks;

static void logger(void *env, const char *name, int status, const char *category, const char *fmt, ...)
{
    (void)env;
    (void)name;
    (void)category;
    if (status >= 2) {
        va_list ap;
        va_start(ap, fmt);
        vfprintf(stderr, fmt, ap);
        fprintf(stderr, "\n");
        va_end(ap);
    }
}

static double now(clockid_t id)
{
    struct timespec ts;
    clock_gettime(id, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static void *read_file(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    void *buf = malloc((size_t)n);
    if (buf && fread(buf, 1, (size_t)n, f) != (size_t)n) {
        free(buf);
        buf = NULL;
    }
    fclose(f);
    *size = (size_t)n;
    return buf;
}

int main(int argc, char **argv)
{
    if (argc < 11)
        return 2;
    int steps = atoi(argv[7]), repeat = atoi(argv[9]);
    double H = atof(argv[8]);
    size_t table_size, image_size;
    double *table = read_file(argv[6], &table_size);
    void *image = read_file(argv[5], &image_size);
    if (!table || !image)
        return 4;
    int n_in = (int)table[0], n_point = (int)table[1], n_out = (int)table[2];
    vr_t *vr_in = malloc(sizeof(vr_t) * n_in), *vr_out = malloc(sizeof(vr_t) * n_out);
    for (int i = 0; i < n_in; i++)
        vr_in[i] = (vr_t)table[3 + i];
    for (int i = 0; i < n_out; i++)
        vr_out[i] = (vr_t)table[3 + n_in + i];
    const double *rows = table + 3 + n_in + n_out;
    const int width = n_in + n_point;
    double *out = malloc(sizeof(double) * n_out), *out_rt = NULL;

    void *lib = open_library(argv[1]);
    void *rt = open_library(argv[4]);
    if (!lib || !rt) {
        fprintf(stderr, "dlopen: %s\n", library_error());
        return 5;
    }
    fmi2Component (*instantiate)(const char *, int, const char *, const char *, const Callbacks *, int, int) =
        sym(lib, "fmi2Instantiate");
    void (*free_instance)(fmi2Component) = sym(lib, "fmi2FreeInstance");
    int (*setup)(fmi2Component, int, double, double, int, double) = sym(lib, "fmi2SetupExperiment");
    int (*enter)(fmi2Component) = sym(lib, "fmi2EnterInitializationMode");
    int (*leave)(fmi2Component) = sym(lib, "fmi2ExitInitializationMode");
    int (*set_real)(fmi2Component, const vr_t *, size_t, const double *) = sym(lib, "fmi2SetReal");
    int (*get_real)(fmi2Component, const vr_t *, size_t, double *) = sym(lib, "fmi2GetReal");
    int (*get_integer)(fmi2Component, const vr_t *, size_t, int *) = sym(lib, "fmi2GetInteger");
    int (*do_step)(fmi2Component, double, double, int) = sym(lib, "fmi2DoStep");
    int (*get_state)(fmi2Component, void **) = sym(lib, "fmi2GetFMUstate");
    int (*state_size)(fmi2Component, void *, size_t *) = sym(lib, "fmi2SerializedFMUstateSize");
    int (*serialize)(fmi2Component, void *, char *, size_t) = sym(lib, "fmi2SerializeFMUstate");
    void *(*body_create)(const void *, size_t, char *, size_t) = sym(rt, "ffrf_body_create");
    void *(*body_array)(void *, const char *, size_t *, char *) = sym(rt, "ffrf_body_array");
    int (*body_set_state)(void *, const double *, size_t) = sym(rt, "ffrf_body_set_state");
    int (*body_advance)(void *, int, int, double, double, double *, double *, int *, int *) = sym(rt, "ffrf_body_advance");
    void (*body_record)(const void *, double *) = sym(rt, "ffrf_body_record");
    Callbacks cb = {logger, calloc, free, NULL, NULL};

    double best_fmu = 1e300, best_rt = 1e300, first = 0.0;
    char err[512];
    const char *step_log = argc >= 13 ? argv[11] : NULL;
    const vr_t vr_iter = step_log ? (vr_t)atoi(argv[12]) : 0;
    double *log_rows = step_log ? malloc(sizeof(double) * 3 * (size_t)steps) : NULL;
    if (step_log && !log_rows)
        return 4;
    int logged = 0, step_status = 0;
    for (int r = 0; r < (step_log ? 1 : repeat); r++) {
        /* the FMU */
        double w0 = now(CLOCK_MONOTONIC);
        fmi2Component c = instantiate("bench", 1, argv[3], argv[2], &cb, 0, 0);
        if (!c || setup(c, 0, 0.0, 0.0, 0, 0.0) || enter(c) || set_real(c, vr_in, (size_t)n_in, rows) || leave(c))
            return 6;
        /* the FMU's initial state for the runtime's body (model.c: the body state ends the serialized state) */
        void *st = NULL;
        size_t size = 0;
        if (get_state(c, &st) || state_size(c, st, &size))
            return 7;
        char *bytes = malloc(size);
        if (serialize(c, st, bytes, size))
            return 7;
        uint64_t n_body = 0;
        memcpy(&n_body, bytes + 16, 8);
        double *init = malloc(sizeof(double) * n_body);
        memcpy(init, bytes + size - 8 * n_body, 8 * n_body);
        double c0 = now(CLOCK_PROCESS_CPUTIME_ID);
        for (int k = 0; k < steps; k++) {
            if (k && set_real(c, vr_in, (size_t)n_in, rows + (size_t)k * width))
                return 8;
            if (step_log) {
                double w = now(CLOCK_MONOTONIC), u = now(CLOCK_THREAD_CPUTIME_ID);
                step_status = do_step(c, k * H, H, 1);
                double u1 = now(CLOCK_THREAD_CPUTIME_ID), w1 = now(CLOCK_MONOTONIC);
                int it = 0;
                if (step_status)
                    break;
                if (get_integer(c, &vr_iter, 1, &it))
                    return 10;
                log_rows[3 * k] = w1 - w;
                log_rows[3 * k + 1] = u1 - u;
                log_rows[3 * k + 2] = it;
                logged = k + 1;
            } else if (do_step(c, k * H, H, 1))
                return 9;
            if (get_real(c, vr_out, (size_t)n_out, out))
                return 10;
            if (k == 0 && r == 0)
                first = now(CLOCK_MONOTONIC) - w0;
        }
        double t_fmu = now(CLOCK_PROCESS_CPUTIME_ID) - c0;
        if (t_fmu < best_fmu)
            best_fmu = t_fmu;
        free_instance(c);
        free(bytes);
        if (step_log) {
            FILE *f = fopen(step_log, "wb");
            if (!f || fwrite(log_rows, sizeof(double), 3 * (size_t)logged, f) != 3 * (size_t)logged)
                return 15;
            fclose(f);
            free(init);
            printf("steps %d status %d\n", logged, step_status);
            return step_status ? 20 + step_status : 0;
        }
        /* the runtime's body, the same inputs through the same rule */
        void *b = body_create(image, image_size, err, sizeof err);
        if (!b) {
            fprintf(stderr, "%s\n", err);
            return 11;
        }
        if (body_set_state(b, init, (size_t)n_body))
            return 12;
        size_t count;
        char kind;
        double *point = body_array(b, "point_values", &count, &kind);
        if (!point || (int)count != n_point)
            return 13;
        int n_int = atoi(argv[10]);
        if (!out_rt)
            out_rt = malloc(sizeof(double) * 4096);
        c0 = now(CLOCK_PROCESS_CPUTIME_ID);
        for (int k = 0; k < steps; k++) {
            memcpy(point, rows + (size_t)k * width + n_in, sizeof(double) * n_point);
            int status = 0, worst = 0;
            if (body_advance(b, 2, n_int, H / n_int, k * H, out_rt, NULL, &status, &worst) != n_int || status)
                return 14;
        }
        body_record(b, out_rt);
        double t_rt = now(CLOCK_PROCESS_CPUTIME_ID) - c0;
        if (t_rt < best_rt)
            best_rt = t_rt;
        free(init);
        void (*body_free)(void *) = sym(rt, "ffrf_body_free");
        body_free(b);
    }
    printf("fmu_cpu %.9f runtime_cpu %.9f first_wall %.9f\n", best_fmu, best_rt, first);
    return 0;
}
