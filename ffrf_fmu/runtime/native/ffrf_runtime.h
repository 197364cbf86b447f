/* The C runtime of ffrf-fmu's flexible bodies: the public interface (what the Python binding,
 * runtime/native/binding.py, and the FMI wrappers call). One `ffrf_body` per body instance; no
 * global state. */
#ifndef FFRF_RUNTIME_H
#define FFRF_RUNTIME_H

#include <stddef.h>
#include <stdint.h>

#define FFRF_RUNTIME_VERSION 4        /* of this interface and of the body image format */

/* statuses of a step (the numpy path's StepFailure causes) */
enum { FFRF_OK = 0, FFRF_NOT_FINITE = 1, FFRF_NOT_CONVERGED = 2, FFRF_NOT_FACTORED = 3, FFRF_ROTATION_ALIAS = 4,
       FFRF_BAD_STEP = 5, FFRF_ITERATION_CAP = 6 /* no convergence within iteration_cap iterations */ };
/* The words of a step's status (the numpy path's StepFailure messages): a static string. */
const char *ffrf_status_text(int status);
/* the gyroscopic terms' two parts: the elastic Coriolis G(W0) (53), the inertia coupling S(q) r (55) */
enum { FFRF_CORIOLIS = 1, FFRF_COUPLING = 2 };
/* where a step's inputs come from */
enum { FFRF_GIVEN = 0, FFRF_SCHEDULED = 1, FFRF_EXTRAPOLATED = 2 };

#define FFRF_OUTPUT_WIDTH 30  /* output columns per port: r, R (row-major), v, w, f, t, a, dw (runtime/outputs.py) */
#define FFRF_N_ENERGIES 4     /* kinetic_rigid, kinetic_elastic, strain, work_external */
#define FFRF_POINT_WIDTH 30    /* runtime/input_rule.py COLUMNS: r 0, v 3, a 6, R 9, w 18, dw 21, f 24, t 27 */

typedef struct ffrf_body ffrf_body;

/* A body from its image (`size` bytes, runtime/native/image.py); NULL with a message in err
 * (err_len bytes) when the image is damaged, of another version or inconsistent. */
ffrf_body *ffrf_body_create(const void *image, size_t size, char *err, size_t err_len);
/* The checksum of an image's payload (`size` bytes; FNV-1a 64 over its 8-byte words, image.py `checksum`),
 * for an image packed in the process that creates the body from it (runtime/native/binding.py). */
uint64_t ffrf_image_checksum(const void *payload, uint64_t size);
void ffrf_body_free(ffrf_body *b);

/* The address and size (in elements) of a named array of the body (state, inputs, springs,
 * schedule, point_values, lu, data): NULL if there is none of that name. kind: 'd' double, 'q' int64,
 * 'i' int32. Used by the Python binding to view the body's memory as numpy arrays. */
void *ffrf_body_array(ffrf_body *b, const char *name, size_t *count, char *kind);
/* Scalars of the body, by name (t, iterations, tol, max_iter, rho_inf, lu_version ...). */
int ffrf_body_get_scalar(const ffrf_body *b, const char *name, double *value);
int ffrf_body_set_scalar(ffrf_body *b, const char *name, double value);

/* Structural damping from the body's arrays damp_zeta [n] (ratio per mode) and damp_ab [2]
 * (Rayleigh alpha, beta), set before a run: rebuilds every superelement's D (runtime/damping.py) without
 * an eigensolver. Returns 0, or -1 when a value is negative or not finite (D is then left unchanged). */
int ffrf_damping_update(ffrf_body *b);

/* The schedule of a scene's run (FFRF_SCHEDULED; simulate.scene_schedule): arrays of the caller's,
 * read during ffrf_body_advance. r0 [n_ports][3], kind [n_ports][2] (-1: none), prm, axis
 * [n_ports][2][3], load_port [n_loads], load_window [n_loads][2], load_fm [n_loads][2][3]. */
void ffrf_body_set_schedule(ffrf_body *b, double *r0, int64_t *kind, double *prm, double *axis, int64_t *load_port,
                            double *load_window, double *load_fm, int n_loads);

/* n steps of h from the body's time, inputs by kind (FFRF_GIVEN: as set in the inputs arrays;
 * FFRF_SCHEDULED: from the schedule, every step's output row into rows[k] and its time into
 * times[k]; FFRF_EXTRAPOLATED: extrapolated from the point values at t_c, the last step's row into rows).
 * Returns the steps completed; *status the status of the first failed step (FFRF_OK if none),
 * *worst the most Newton iterations of a step. A failed step leaves the state at the last one. */
int ffrf_body_advance(ffrf_body *b, int kind, int n, double h, double t_c, double *rows,
                      double *times, int *status, int *worst);

/* The consistent initial state at t0 (BodySystem.initialize) of a body at its reference state: placed rigidly
 * on the motion inputs at t0, port_displacements ([n_ports][3], model order; NULL: none) added and relaxed to a
 * static shape, the rigid velocity field of velocity, angular_velocity about origin (or the motion inputs' rates),
 * consistent rates from a backward-Euler micro-step of FFRF_MICRO_STEP, the port loads and power at t0. Inputs
 * by kind: FFRF_GIVEN: those at t0 as set in the inputs arrays and the springs' r_in, v_in, R_in, w_in on entry,
 * those of the micro-step in next, the same arrays one after the other (xN_p, RN_p, zN_p, f_in, t_in, r_in,
 * v_in, R_in, w_in; a standalone run's scene functions at t0 + FFRF_MICRO_STEP); FFRF_EXTRAPOLATED: both from
 * the point values at t0 (an FMU; next unused). Returns 0; a step status (> 0) of the micro-step, *last its
 * last increment (lu_meta[1]), the state that before the micro-step; FFRF_INIT_NO_EQUILIBRIUM, *last the
 * relaxation's last correction; FFRF_INIT_NO_MEMORY. */
#define FFRF_MICRO_STEP 1e-6
enum { FFRF_INIT_NO_EQUILIBRIUM = -1, FFRF_INIT_NO_MEMORY = -2 };
int ffrf_body_initialize(ffrf_body *b, double t0, const double velocity[3], const double angular_velocity[3],
                         const double origin[3], const double *port_displacements, int kind, const double *next,
                         double *last);

/* The output row at the current state (FFRF_OUTPUT_WIDTH n_ports + FFRF_N_ENERGIES + 1 doubles). */
void ffrf_body_record(const ffrf_body *b, double *row);

/* The whole state (everything the next step depends on, the factorization included) as doubles:
 * its size, a copy out, a copy in (checked: 0 ok, -1 wrong size). */
size_t ffrf_body_state_size(const ffrf_body *b);
void ffrf_body_get_state(const ffrf_body *b, double *out);
int ffrf_body_set_state(ffrf_body *b, const double *in, size_t size);

/* The body's equations at a given stage, without port loads (gravity included): the assembled residual
 * F [ny] (rows summed at the shared nodes) at the configuration p [ny] (the stage vector: positions, eta
 * and velocities in their rate slots; rotation slots unread), the rates yd [ny] and the rotations
 * R [N + E][3][3] (nodes, then CM frames), and, if jac, every superelement's local blocks F_ydot (Fz) and
 * F_y (Fy) [E][nv + nc][nc + nv] (runtime/equations.py residual_and_jacobian's rows and columns).
 * BodySystem's residual and linearizations on the C runtime (its initial state, runtime/initial_conditions.py;
 * linear.py). Returns 0, or -1 if an array is missing. */
int ffrf_body_residual(ffrf_body *b, const double *p, const double *yd, const double *R, int jac, double *F,
                       double *Fz, double *Fy);

/* ---- for tests ---- */
/* The local rows F [nv + nc] of superelement e at the stage (p [ny], yd [ny], R [N + E][3][3]) and, if
 * jac, its blocks F_ydot (Fz) and F_y (Fy) [nv + nc][nc + nv] (runtime/equations.py residual_and_jacobian's
 * rows and columns), computed in the body's own work space; jac = 2: the blocks in a refresh's form (the k_q
 * rows premultiplied by M_bar^-1, the columns of motion-driven rates not formed: superelement.c `jacobian`).
 * Returns 0, or -1 if e is not a superelement of the body or an array is missing. */
int ffrf_body_superelement(ffrf_body *b, int e, const double *p, const double *yd, const double *R, int jac,
                           double *F, double *Fz, double *Fy);

#endif
