/* The body FMU's model interface: what an instance holds and does, below the thin FMI 2.0 layer of
 * fmi2Functions.c and the FMI 3.0 layer of fmi3Functions.c, one per binary (the layout of the Modelica
 * Association's Reference-FMUs: fmi2Functions and fmi3Functions over a small model interface with one
 * instance struct of named fields).
 *
 * The binary is body-independent: everything about the body comes from resources/body.bin
 * (resource.c; written by ffrf_fmu/fmu/native/resource.py): the variable table of
 * ffrf_fmu/fmu/variables.py, the maps from variables to the runtime's point values and output row, and
 * one runtime image (runtime/native/image.py) per term set the FMU offers. The body steps in the C
 * runtime (runtime/native), the same code as a standalone run.
 *
 * No global state: instances are independent. Allocation at instantiation and initialization only,
 * never in doStep. */
#ifndef FFRF_FMU_MODEL_H
#define FFRF_FMU_MODEL_H

#include <stddef.h>
#include <stdint.h>

#include "fmi2FunctionTypes.h" /* the standard's types only: the functions are the FMI layer's, above */
#include "ffrf_runtime.h"
#include "resource.h"

#define FMU_MESSAGE 1024          /* longest kept message (initialization failure, last discard) */
#define FMU_STATE_VERSION 1       /* of a serialized FMU state */
#define FMU_API(m) ((m)->fmi ? (m)->fmi : "fmi2") /* the FMI function prefix of messages */

typedef enum {
    MODE_INSTANTIATED = 1, MODE_INITIALIZATION = 2, MODE_STEP = 4, MODE_TERMINATED = 8, MODE_ERROR = 16
} fmu_mode;

/* The log categories modelDescription.xml declares (fmu/native/__init__.py `LOG_CATEGORIES`, the same names in
 * the same order): one per status a message can have, logStatusWarning .. logStatusFatal, and logAll for the
 * rest (OK: what a step did). fmi2/3SetDebugLogging switches them by name, all of them for no names (FMI 2.0.4
 * section 2.1.5, FMI 3.0 section 2.3.1); at instantiation the status categories are on and logAll is loggingOn. */
#define FMU_LOG_CATEGORIES 5
extern const char *const fmu_log_category[FMU_LOG_CATEGORIES];
unsigned model_log_categories(int logging_on);

typedef struct {
    char *name;                   /* instance name */
    fmi2CallbackFunctions cb;
    /* the FMI layer above (NULL: FMI 2.0): fmi3Functions.c sets its prefix "fmi3" for the messages and a
     * sink that hands them to its logMessage callback (fmi2's logger is then unused) */
    const char *fmi;
    void (*sink)(void *m, int status, const char *category, const char *message);
    unsigned log_categories;      /* a bit per FMU_LOG_CATEGORIES entry: its messages are logged */
    fmu_description desc;
    fmu_mode mode;
    double *values;               /* [n_vars] every variable by value reference (Integers as doubles) */
    double *start_values;         /* [n_vars] (fmi2Reset) */
    double start_time, stop_time;
    int has_stop;
    ffrf_body *body;              /* created at initialization, for the term set of solver.terms */
    int body_terms;
    char failure[FMU_MESSAGE];    /* a failed initialization: every doStep reports it */
    char discarded[FMU_MESSAGE];  /* the last discard's message while the FMU stays at its t_c */
    int initialized;              /* initialized_with holds the inputs and parameters of the last initialization */
    double *initialized_with;     /* [n_vars] */
    double *point_values;         /* [n_ports][FFRF_POINT_WIDTH] work: the point values of a step */
    double *row;                  /* output row, then the probes [n_probes][3], eta [n_modal], its rates [n_modal] */
    size_t state_size;            /* ffrf_body_state_size */
    double *rollback;             /* [state_size] the body at t_c of the current doStep (whole: ffrf_body_get_state) */
    uint64_t rollback_lu_version; /* the factors in rollback are those of this matrix version */
    int rollback_lu_valid;        /* ... when set, and then a doStep copies only the rest (`small_copy`) */
    size_t small_size;            /* the state's doubles before the factors (0: always copy the whole state) */
    double *ref_state;            /* [state_size] the body as created: the reference state initialization starts from */
    /* the last successful communication step (directional derivatives) */
    int have_last;
    double last_tc, last_H;
    int last_n;
    double *last_values;          /* [n_vars] */
    double *end_state;            /* [state_size] work of the derivatives */
    double *deriv_values;         /* [n_vars] work */
    double *deriv_sides;          /* [2][n_vars] work */
} fmu_instance;

/* model.c: every function returns fmi2OK, fmi2Discard or fmi2Error and logs the cause */
void fmu_log(fmu_instance *m, fmi2Status status, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
/* the modes of the calls (FMI 2.0 section 4.2.4, FMI 3.0 section 4.1): values are read after instantiation, set
 * before step mode ends; the FMU state calls and reset in any */
#define MODES_ANY (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP | MODE_TERMINATED | MODE_ERROR)
#define MODES_GET (MODE_INITIALIZATION | MODE_STEP | MODE_TERMINATED | MODE_ERROR)
#define MODES_SET (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP)
enum { TYPE_BOOLEAN = 2, TYPE_STRING = 3 }; /* FMI 2.0's other types (TYPE_REAL, TYPE_INTEGER: resource.h): none here */
enum { AS_FLOAT64 = 0, AS_INT = 1, AS_INT32 = 2 }; /* what a value array holds: double, int, int32_t */

/* An instance just allocated (zeroed, its callbacks set) made ready: its name, resources/body.bin from the
 * resource URI, the token (`token_word`: GUID, instantiation token) checked against it, its arrays. fmi2OK, or
 * fmi2Error logged under `call` (with `refusal`, the reason the wrapper refuses the instantiation, if not NULL);
 * model_free then frees what was made. */
fmi2Status model_instantiate(fmu_instance *m, const char *call, const char *name, const char *resource_uri,
                             const char *token, const char *token_word, const char *refusal);
/* m, if `call` is allowed in its mode (a mask of MODE_*), else NULL (fmi2Error logged); NULL for NULL */
fmu_instance *model_allowed(fmu_instance *m, const char *call, int modes);
/* a call this FMU does not provide: fmi2Error, logged with `why` */
fmi2Status model_refused(fmu_instance *m, const char *call, const char *why);
/* The calls that move an instance between the modes, each checked to be allowed in the mode it is in (fmi2Error
 * logged under `call` if not): logging on or off; the experiment's start and stop time, then initialization mode
 * (FMI 3.0's fmi3EnterInitializationMode is both); its end, which initializes the body; terminate; reset to the
 * instantiated mode and the start values. */
fmi2Status model_set_logging(fmu_instance *m, const char *call, int on, size_t n_categories,
                             const char *const categories[]);
fmi2Status model_setup_experiment(fmu_instance *m, const char *call, double start_time, int has_stop, double stop_time);
fmi2Status model_enter_initialization(fmu_instance *m, const char *call);
fmi2Status model_exit_initialization(fmu_instance *m, const char *call);
fmi2Status model_terminate(fmu_instance *m, const char *call);
fmi2Status model_reset(fmu_instance *m, const char *call);
void model_free(fmu_instance *m);
/* The get and set calls of FMI 2.0 (type TYPE_*, value an array of it): the references checked (known, of the
 * type: named whatever the mode), the mode, the arrays, then the values. */
fmi2Status model_get_values(fmu_instance *m, const char *call, int type, const fmi2ValueReference vr[], size_t n,
                            void *value);
fmi2Status model_set_values(fmu_instance *m, const char *call, int type, const fmi2ValueReference vr[], size_t n,
                            const void *value);
/* The values of scalars of checked references, an array of `as` (AS_*); outputs read in initialization mode
 * reflect the inputs and parameters set so far. Set refuses an output, and a parameter in step mode. */
fmi2Status model_get_scalars(fmu_instance *m, const fmi2ValueReference vr[], size_t n, int as, void *value);
fmi2Status model_set_scalars(fmu_instance *m, const char *call, const fmi2ValueReference vr[], size_t n, int as,
                             const void *value);
/* doStep from t_c over H, in step mode only (refused and logged under `call` otherwise) */
fmi2Status model_do_step(fmu_instance *m, const char *call, double t_c, double H);
/* The two meanings of a directional derivative (docs/fmu.md, "Directional derivatives"):
 * DERIV_FMI  FMI 2.0's and 3.0's: the partial derivatives of the outputs with respect to the inputs at the current
 *            communication point (v_unknown = h(v_known, v_rest)); zero here, no output depends directly on an input
 *            (ModelStructure dependencies=""). fmi2GetDirectionalDerivative, fmi3GetDirectionalDerivative, the adjoint.
 * DERIV_STEP the derivatives of the last communication step: of the outputs at t_c + H with respect to the inputs
 *            set at t_c for [t_c, t_c + H] (FMU input rule: motion extrapolated, loads held), the state at t_c fixed (central differences of two re-runs). Not an FMI
 *            function: ffrf2GetStepDerivative, ffrf3GetStepDirectionalDerivative, ffrf3GetStepAdjointDerivative,
 *            for the interface-Jacobian master (ffrf_fmu/master/interface.py). */
enum { DERIV_FMI = 0, DERIV_STEP = 1 };
fmi2Status model_directional_derivative(fmu_instance *m, int meaning, const fmi2ValueReference unknown[],
                                        size_t n_unknown, const fmi2ValueReference known[], size_t n_known,
                                        const fmi2Real seed[], fmi2Real out[]);
/* The transposed product seed^T J [n_known] of the derivatives of `meaning` (FMI 3.0's adjoint derivative), one
 * directional derivative per known element. */
fmi2Status model_adjoint_derivative(fmu_instance *m, const char *call, int meaning, const fmi2ValueReference unknown[],
                                    size_t n_unknown, const fmi2ValueReference known[], size_t n_known,
                                    const fmi2Real seed[], fmi2Real out[]);
/* FMU state objects (fmi2GetFMUstate ... fmi2DeSerializeFMUstate and their FMI 3.0 twins are these; `call` names
 * the function in the messages; any mode, NULL m or pointers are fmi2Error): a saved state is its serialized form
 * in one allocation, owned through the caller's pointer. get reuses *state when it has the size; deserialize
 * checks the bytes first (a damaged state is refused there, not at set); free of NULL or of a NULL pointer does
 * nothing. */
fmi2Status model_state_get(fmu_instance *m, const char *call, void **state);
fmi2Status model_state_set(fmu_instance *m, const char *call, const void *state);
void model_state_free(void **state);
fmi2Status model_state_size(fmu_instance *m, const char *call, const void *state, size_t *size);
fmi2Status model_state_serialize(fmu_instance *m, const char *call, const void *state, unsigned char *out,
                                 size_t size);
fmi2Status model_state_deserialize(fmu_instance *m, const char *call, const unsigned char *in, size_t size,
                                   void **state);
/* FMU state: a self-contained copy, and its serialized form (version, size, checksum) */
size_t model_serialized_size(const fmu_instance *m);
void model_serialize(const fmu_instance *m, unsigned char *out);
fmi2Status model_deserialize(fmu_instance *m, const unsigned char *in, size_t size);
fmi2Status model_serialized_check(fmu_instance *m, const unsigned char *in, size_t size); /* version, FMU, checksum */
double model_time(const fmu_instance *m); /* the body's time: the last successful communication point */

/* py_repr: a double as Python's repr writes it (the messages quote parameters as the Python FMU did) */
const char *py_repr(double x, char *buf, size_t len);

#endif
