/* The layout of a body of the C runtime (the bottom layer, every file includes it): one struct with named fields (the reduced data, the integrator's
 * index maps, the state, the inputs of a step, the compliant ports' springs, the work arrays).
 *
 * Every array is allocated once, in ffrf_body_create (body.c), from a versioned binary image of
 * the body (runtime/native/image.py writes it); nothing is allocated in a step and no state is
 * global: instances are independent, one instance per thread is safe.
 *
 * Array shapes are given in brackets with the dimension names of `ffrf_dims`; every array is
 * C-ordered (row-major) and contiguous. Indices are int64 (the image stores them so).
 * The names are those of runtime/equations.py, runtime/integrator.py and runtime/newton.py (docs/equations.md).
 */
#ifndef FFRF_LAYOUT_H
#define FFRF_LAYOUT_H

#include <stddef.h>
#include <stdint.h>

#include "ffrf_runtime.h"

typedef int64_t idx_t;

#define FFRF_PI 3.14159265358979323846

/* The sizes of a body. N boundary nodes, E superelements, nb boundary nodes per superelement,
 * nm modes per superelement, n = 6 nb + nm reduced dofs, nc = 6 + nm + 6 nb local configuration
 * columns, nv = 6 + n local velocity columns, ny global rates, nf Newton unknowns. */
typedef struct {
    int N, E, nb, nm, n, nc, nv, ny, nf;
    int n_vk;      /* rows of the membrane strain vk_a (0: no stiffening strain) */
    int n_w1;      /* leading size of W1 (n, or 0: no deformation-dependent inertia) */
    int n_w2;      /* leading sizes of W2 (n, or 0: no quadratic inertia) */
    int n_g;       /* size of G's matrices (n, or 1 for the placeholder of the linear set) */
    int n_world;   /* world triplets of ydot (rows of world_idx) */
    int n_lin;     /* entries of lin_slots: 3N + 3E + E nm + E nv */
    int n_fixed;   /* motion-prescribed rates */
    int n_mx;      /* motion-driven translations */
    int n_mT;      /* motion-driven rotation slots (3 per motion-driven rotation) */
    int n_fields;  /* fields of the Newton increments' scaling (max field_of + 1) */
    int n_int;     /* internal unknowns of a superelement: 6 + nm + nv (factor.c) */
    int n_be;      /* boundary dofs of a superelement: 6 nb */
    int n_bnd;     /* free boundary-node unknowns: nf - E n_int */
    int n_ports;   /* ports, in the model's order */
    int n_springs; /* compliant ports */
    int n_loads;   /* load windows of a scene's schedule (0 outside a scheduled run) */
    int n_el;      /* modes of a superelement in the damping basis: n, or 0 (no damping data) */
} ffrf_dims;

/* The reduced data and the integrator's maps: constant after creation. */
typedef struct {
    int gyro;                 /* FFRF_CORIOLIS | FFRF_COUPLING bits of the gyroscopic terms */
    int stiff;                /* 1: the deformation-dependent inertia W1 [W2] is on (stiffening or `full`) */
    const double *K;          /* [E][n][n]     K_bar (76) */
    const double *M;          /* [E][n][n]     M_bar (76) */
    const double *G;          /* [E][3][n_g][n_g] G_k = Y^T M_k Y (53) */
    const double *W1;         /* [E][n_w1][3][3] */
    const double *W2;         /* [E][n_w2][n_w2][3][3] */
    const double *vk_a;       /* [E][n_vk][n]  membrane strain, linear part */
    const double *vk_B;       /* [E][n_vk][n][n] membrane strain, quadratic part */
    const double *mass;       /* [E] */
    const double *J0;         /* [E][3][3] inertia about the CM (13) */
    const double *X_B;        /* [E][nb][3] boundary nodes relative to the CM, body axes */
    const idx_t *se_nodes;    /* [E][nb]       global boundary node of each local node */
    const idx_t *cfg_map;     /* [E][nc]       local configuration column -> global rate */
    const idx_t *vel_map;     /* [E][nv]       local velocity column -> global rate */
    const double *gravity;    /* [3] */
    const idx_t *rot_slots;   /* [N + E][3]    rate slots of every rotation (nodes, then CM frames) */
    const idx_t *newton_idx;  /* [nf]          Newton order -> global rate */
    const idx_t *newton_pos;  /* [ny]          global rate -> Newton order (>= nf: not an unknown) */
    int k3;                   /* 3 x the free world triplets that lead the Newton order */
    const idx_t *field_of;    /* [nf]          scaling field of each Newton unknown */
    double theta_refresh, kept_accept, kept_radius, keep_miss; /* the Newton policy (newton.py) */
    double near_miss, near_contraction;                /* NEAR_MISS, NEAR_CONTRACTION: the KEEPS verdict */
    double wide_miss, kept_age;                        /* WIDE_MISS, KEPT_AGE: a kept matrix after a miss below WIDE_MISS */
    int refresh_min, refresh_max;                      /* REFRESH_AFTER */
    const idx_t *world_idx;   /* [n_world][3] */
    const idx_t *lin_slots;   /* [n_lin]       stage slots of xN, x0, eta, v (in that order) */
    const idx_t *fixed_idx;   /* [n_fixed] */
    const idx_t *motion_x;    /* [n_mx]        nodes with a motion-driven translation */
    const idx_t *motion_x_slots; /* [3 n_mx] */
    const idx_t *motion_T_slots; /* [n_mT] */
    const double *stage_mask; /* [ny] */
    const double *motion_parts; /* [N][2][3]   1 on motion-driven node dofs */
    /* ports (runtime/input_rule.py port_codes) */
    const idx_t *port_node;   /* [n_ports] */
    const idx_t *port_mode;   /* [n_ports][2] translation, rotation: 0 force, 1 motion, 2 compliant */
    const idx_t *port_spring; /* [n_ports]     index among the compliant ports, -1 */
    /* compliant ports (runtime/coupling.py) */
    const idx_t *spring_node; /* [n_springs] */
    const idx_t *spring_trans;/* [n_springs]   1: translation compliant */
    const idx_t *spring_rot;  /* [n_springs]   1: rotation compliant */
    /* structural damping (runtime/damping.py): the elastic free-free modes of each reduced superelement */
    const double *damp_MPhi;  /* [E][n][n_el]  M_bar Phi, Phi mass-normalized */
    const double *damp_omega; /* [E][n_el]     their circular frequencies [rad/s] */
} ffrf_data;

/* Structural damping: the settable ratios and coefficients and the matrices they make
 * (ffrf_damping_update): D = MPhi diag(c) MPhi^T, c_i = 2 zeta_i omega_i + alpha + beta omega_i^2. */
typedef struct {
    double *zeta;      /* [n_el]       damping ratio of each mode */
    double *ab;        /* [2]          Rayleigh alpha [1/s], beta [s] */
    double *D;         /* [E][n_d][n_d] n_d = n with damping data, else 0 */
    int on;            /* 1: some c_i > 0, the elastic force (78) carries D q_bar_dot */
} ffrf_damping;

/* Everything the next step depends on (BodySystem._STATE_FIELDS, then the scalars). */
typedef struct {
    double *xN;        /* [N][3] */
    double *RN;        /* [N][3][3] */
    double *x0;        /* [E][3] */
    double *R0;        /* [E][3][3] */
    double *eta;       /* [E][nm] */
    double *v;         /* [E][nv] */
    double *yd;        /* [ny] */
    double *yd_prev;   /* [ny] */
    double *yd_prev2;  /* [ny] */
    double *a;         /* [ny] */
    double *fN;        /* [N][3] */
    double *tN;        /* [N][3] */
    double *energy;    /* [2] work, power */
    double t;
    int iterations;    /* Newton iterations of the last step */
} ffrf_state;

/* The inputs of one step (BodySystem._read_inputs): prescribed frames and rates, loads. */
typedef struct {
    double *xN_p;      /* [N][3] */
    double *RN_p;      /* [N][3][3] */
    double *zN_p;      /* [N][6] */
    double *f_in;      /* [N][3] */
    double *t_in;      /* [N][3] */
} ffrf_inputs;

/* Compliant ports' spring-dampers: settable stiffness and far-end inputs, the loads they apply. */
typedef struct {
    double *KC;        /* [n_springs][4][3] K_t, C_t, K_r, C_r */
    double *r_in;      /* [n_springs][3] */
    double *v_in;      /* [n_springs][3] */
    double *R_in;      /* [n_springs][3][3] */
    double *w_in;      /* [n_springs][3] */
    double *loads;     /* [N][2][3] force, moment (world) of the springs, zero elsewhere */
} ffrf_springs;

/* A scene's schedule (simulate.scene_schedule after the ports' codes), for FFRF_SCHEDULED. */
typedef struct {
    double *r0;          /* [n_ports][3] */
    idx_t *kind;         /* [n_ports][2]  time function codes (drives.CODES), -1 none */
    double *prm;         /* [n_ports][2][3] */
    double *axis;        /* [n_ports][2][3] */
    idx_t *load_port;    /* [n_loads] */
    double *load_window; /* [n_loads][2] */
    double *load_fm;     /* [n_loads][2][3] */
} ffrf_schedule;

/* The factorization of the iteration matrix, kept across steps (integrator `_lu`). */
typedef struct {
    double *luT;       /* [nf][nf] LU factors, transposed (luT^T is LAPACK's/scipy's LU) */
    int *piv;          /* [nf]     0-based row interchanges */
    double *meta;      /* [12]     valid, beta, R_ref (9, row-major), verdict (0 drop, 1 serves, 2 keeps: integrator SERVES, KEEPS) */
    double *JT;        /* [nf][nf] the iteration matrix being built (transposed) */
    uint64_t version;  /* incremented at every refresh: a caller's copy is stale when it differs */
    uint64_t refreshed; /* the last ffrf_step's refreshes: bit i - 1 set when Newton built the matrix at iteration i
                        * (a retry's iterations counted after the failed attempt's max_iter, as state.iterations);
                        * the scalar "refreshed": the decisions a test replays on the numpy path */
} ffrf_lu;

/* Which Newton unknowns are whose (factor.c): set at creation from the maps (body.c `partition`). */
typedef struct {
    idx_t *se_unknowns;   /* [E][n_int]  Newton positions of each superelement's own rates */
    idx_t *se_bnd;        /* [E][n_be]   its boundary dofs' index among the node unknowns, -1: motion-driven */
    idx_t *node_unknowns; /* [n_bnd]     Newton positions of the free boundary-node rates */
    idx_t *se_fb;         /* [E][n_be]   its free boundary dofs (index among the node unknowns), the first se_m[e] */
    idx_t *se_m;          /* [E]         their count m_e (ffrf_factor_prepare) */
    size_t entries;       /* the entries of the factorization store that ffrf_factor fills (ffrf_factor_prepare) */
    double *y, *xB, *u, *t; /* [n_int], [n_bnd], [n], [n_int] work of the factorization and the solve */
} ffrf_partition;

typedef struct ffrf_se_work ffrf_se_work; /* superelement.c: work arrays of one superelement */

/* Work arrays of a step (newton_step's and step's locals, allocated at creation). */
typedef struct {
    double *ydw, *p, *R, *F;          /* [ny], [ny], [N + E][3][3], [ny] */
    double *A0, *P0, *c;              /* [ny] */
    double *Rn;                       /* [N + E][3][3] */
    double *theta, *T;                /* [N + E][3], [N + E][3][3] */
    double *Fl, *Fz, *Fy;             /* [nv + nc], [nv + nc][nc + nv] x 2 */
    double *b;                        /* [nf] */
    double *S;                        /* [n_fields] */
    double *row;                      /* [OUTPUT row]: FFRF_OUTPUT_WIDTH n_ports + 5 */
    double *q_rec;                    /* [n] */
    double *M_luT;                    /* [E][n][n] LU factors of each M_bar (transposed), made at creation: accel.c */
    int *M_piv;                       /* [E][n] */
    double *M_inv;                    /* [E][n][n] each M_bar^-1 (column j in row j), made at creation: accel.c; factor.c */
    double *MG;                       /* [E][3][n_g][n_g] M_bar^-1 G_k, made at creation (body.c): superelement.c's k_q rows */
    double *acc;                      /* [3][n] q_bar, q_bar', q_bar'' of accel.c */
    ffrf_se_work *se;                 /* superelement.c */
} ffrf_work;

struct ffrf_body {
    ffrf_dims dims;
    ffrf_data data;
    ffrf_state state;
    ffrf_inputs in;
    ffrf_springs springs;
    ffrf_schedule schedule;
    ffrf_damping damping;
    double *point_values;             /* [n_ports][FFRF_POINT_WIDTH] an FMU's inputs as set at t_c */
    ffrf_lu lu;
    ffrf_partition part;
    ffrf_work work;
    double tol;                       /* Newton tolerance */
    int max_iter;
    int iteration_cap;                /* a step's Newton iterations, a retry's counted, at most this (0: no cap) */
    double rho_inf, am, af, gamma;    /* generalized-alpha coefficients (integrator alpha_coefficients) */
    void *arena;                      /* the one allocation holding every array */
    void *image;                      /* the image's arrays (owned copy) */
};

#endif
