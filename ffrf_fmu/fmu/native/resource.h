/* What resource.c offers the model above it: resources/body.bin found from the resource URI a host passes,
 * read, checked and described (the variable table, the ports, the maps to the runtime's point values and
 * output row, the runtime images and start states per term set). The bottom layer of the FMU's C. */
#ifndef FFRF_FMU_RESOURCE_H
#define FFRF_FMU_RESOURCE_H

#include <stddef.h>
#include <stdint.h>

#include "ffrf_runtime.h"

#define FMU_FORMAT_VERSION 3      /* of resources/body.bin (resource.py FORMAT_VERSION) */
#define FMU_TERM_SETS 3           /* linear, gyroscopic, full (runtime/terms.py TERM_SETS) */

enum { CAUS_INPUT = 0, CAUS_OUTPUT = 1, CAUS_PARAMETER = 2 };
enum { TYPE_REAL = 0, TYPE_INTEGER = 1 };
/* what a unit change of an input moves over a communication step of H (derivatives.py DERIVATIVE_STEPS):
 * a load; a position or rotation (1); a rate (H); an acceleration (H^2 / 2) */
enum { DKIND_LOAD = 0, DKIND_POSITION = 1, DKIND_RATE = 2, DKIND_ACCEL = 3 };
enum { PART_FORCE = 0, PART_MOTION = 1, PART_COMPLIANT = 2 };

typedef struct {
    const char *name;
    int type, causality, dkind;
    double start;
    int has_min, has_max;
    double min, max;
} fmu_variable;

typedef struct {
    const char *name;
    int node, translation, rotation; /* PART_* */
} fmu_port;

/* resources/body.bin, read and checked (resource.c). Arrays point into `blob`. */
typedef struct {
    void *blob;                   /* the descrambled payload (one allocation) */
    char guid[64];
    char description[160];        /* the body's name and version line, for messages */
    int n_vars;
    fmu_variable *vars;
    int n_ports;
    fmu_port *ports;
    const int32_t *point_vr;      /* [n_ports][FFRF_POINT_WIDTH] value reference read into each point-value column, -1 */
    int n_out;
    const int32_t *out_vr;        /* [n_out] output value references ... */
    const int32_t *out_src;       /* [n_out] ... and their position in [output row, probes] */
    int n_probes;
    const int32_t *probe_seen;    /* [n_probes] port rows (eq. 92) */
    const int32_t *probe_frame;
    const double *probe_dX;       /* [n_probes][3] X_seen - X_frame */
    int n_modal;                  /* modal outputs modal.eta[e,i]: superelements x modes (their rates as many) */
    int vr_step, vr_rho_inf, vr_terms, vr_iterations, vr_max_iterations;
    int vr_gravity[3], vr_velocity[3], vr_angular_velocity[3];
    const int32_t *disp_vr;       /* [n_ports][3] initial.<port>.d, -1 */
    const int32_t *coupling_vr;   /* [n_ports][12] <port>.coupling.{k, c, k_rot, c_rot}, -1 */
    int vr_damp_alpha, vr_damp_beta; /* damping.alpha, damping.beta (runtime/damping.py) */
    int n_damp_ratios;            /* 1: damping.ratio for every mode; else one per mode of a superelement */
    const int32_t *damp_ratio_vr; /* [n_damp_ratios] */
    double origin[3];             /* of the initial rigid velocity field */
    const void *image[FMU_TERM_SETS]; /* runtime image per term set (NULL: not in this FMU) */
    size_t image_size[FMU_TERM_SETS];
    /* the start state per term set made at build (resource.py start sections: state code, gravity [3], the
     * START_FIELDS of runtime/start.py); NULL: the FMU starts from rest */
    const double *start[FMU_TERM_SETS];
    size_t start_count[FMU_TERM_SETS]; /* doubles, the code and gravity included */
} fmu_description;

/* The directory of resources from a host's resource URI (file://...) or plain path: 0, or -1 with err set. */
int fmu_resource_path(const char *uri, char *path, size_t len, char *err, size_t err_len);
/* resources/body.bin of the directory `path`, read and checked into d: 0, or -1 with err naming the cause. */
int fmu_description_load(fmu_description *d, const char *path, char *err, size_t err_len);
void fmu_description_free(fmu_description *d);

#endif
