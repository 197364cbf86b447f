/* A body of the C runtime: created from its image (runtime/native/image.py), every array allocated
 * here at once (none in a step), named arrays for the binding and the FMI layer, the state as one
 * vector of doubles. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "body.h"
#include "bytes.h"

/* In an address-sanitizer build every array of the arena is followed by a poisoned red zone, so that a
 * write past an array's end is reported instead of landing silently in its neighbour. */
#if defined(__SANITIZE_ADDRESS__)
void __asan_poison_memory_region(void const volatile *addr, size_t size); /* the sanitizer's runtime (its header
                                                                           * is not shipped by every compiler) */
#define POISON(addr, size) __asan_poison_memory_region((addr), (size))
#define REDZONE 32
#else
#define POISON(addr, size) ((void)(addr), (void)(size))
#define REDZONE 0
#endif

/* ------------------------------------------------------------------ the image */

#define MAGIC "FFRFBODY"
#define NAME_BYTES 24
#define MAX_DIMS 5
#define HEADER_BYTES 32                       /* magic, version u32, count u32, payload u64, checksum u64 */
#define ENTRY_BYTES (NAME_BYTES + 8 + 8 * MAX_DIMS) /* name, kind u8, ndim u8, 6 pad, dims */

typedef struct {
    char name[NAME_BYTES];
    char kind;          /* 'd' or 'q' */
    int ndim;
    uint64_t dims[MAX_DIMS];
    uint64_t count;
    const void *values; /* into the body's copy of the payload, 8-byte aligned */
} entry;

uint64_t ffrf_image_checksum(const void *payload, uint64_t size)
{
    return ffrf_fnv1a_words(payload, (size_t)size);
}

#define MAX_ENTRIES 96

typedef struct {
    entry e[MAX_ENTRIES];
    int count;
} entries;

static const entry *find(const entries *es, const char *name)
{
    for (int i = 0; i < es->count; i++)
        if (strcmp(es->e[i].name, name) == 0)
            return &es->e[i];
    return NULL;
}

static int fail(char *err, size_t len, const char *fmt, const char *a, long long x, long long y)
{
    if (err && len)
        snprintf(err, len, fmt, a, x, y);
    return -1;
}

/* The entries of a payload (copied to `copy`, which the entries point into). */
static int parse(const unsigned char *image, size_t size, unsigned char **copy, entries *es, char *err, size_t len)
{
    if (size < HEADER_BYTES || memcmp(image, MAGIC, 8) != 0)
        return fail(err, len, "not a body image (no %s header)%lld%lld", MAGIC, 0, 0);
    uint32_t version = ffrf_read_u32(image + 8), count = ffrf_read_u32(image + 12);
    uint64_t payload = ffrf_read_u64(image + 16), check = ffrf_read_u64(image + 24);
    if (version != FFRF_RUNTIME_VERSION)
        return fail(err, len, "%sbody image of version %lld, this runtime reads version %lld", "", version,
                    FFRF_RUNTIME_VERSION);
    if (payload != size - HEADER_BYTES || payload % 8 != 0)
        return fail(err, len, "%sbody image truncated or padded: %lld payload bytes announced, %lld present", "",
                    (long long)payload, (long long)(size - HEADER_BYTES));
    if (ffrf_image_checksum(image + HEADER_BYTES, payload) != check)
        return fail(err, len, "%sbody image damaged: checksum mismatch%lld%lld", "", 0, 0);
    if (count > MAX_ENTRIES)
        return fail(err, len, "%sbody image has %lld entries, at most %lld are read", "", count, MAX_ENTRIES);
    *copy = malloc(payload ? payload : 8);
    if (!*copy)
        return fail(err, len, "%sout of memory (%lld bytes)%lld", "", (long long)payload, 0);
    memcpy(*copy, image + HEADER_BYTES, payload);
    const unsigned char *p = *copy, *end = *copy + payload;
    es->count = 0;
    for (uint32_t k = 0; k < count; k++) {
        if ((size_t)(end - p) < ENTRY_BYTES)
            return fail(err, len, "%sbody image truncated in entry %lld%lld", "", k, 0);
        entry *e = &es->e[es->count++];
        memcpy(e->name, p, NAME_BYTES);
        e->name[NAME_BYTES - 1] = '\0';
        e->kind = (char)p[NAME_BYTES];
        e->ndim = p[NAME_BYTES + 1];
        if ((e->kind != 'd' && e->kind != 'q') || e->ndim > MAX_DIMS)
            return fail(err, len, "body image entry %s: kind or dimensions not readable%lld%lld", e->name, 0, 0);
        e->count = 1;
        for (int i = 0; i < MAX_DIMS; i++) {
            e->dims[i] = ffrf_read_u64(p + NAME_BYTES + 8 + 8 * i);
            if (i < e->ndim) {
                if (e->dims[i] > (1u << 24) || (e->dims[i] && e->count > ((uint64_t)1 << 40) / e->dims[i]))
                    return fail(err, len, "body image entry %s: dimension %lld too large%lld", e->name, (long long)e->dims[i], 0);
                e->count *= e->dims[i];
            }
        }
        p += ENTRY_BYTES;
        if ((uint64_t)(end - p) / 8 < e->count)
            return fail(err, len, "body image entry %s: %lld values announced, the image ends first%lld", e->name,
                        (long long)e->count, 0);
        e->values = p;
        p += 8 * e->count;
    }
    return 0;
}

/* ------------------------------------------------------------------ shapes */

/* dimension codes of the shapes below (values >= 0 are literal sizes) */
enum { d_N = -1, d_E = -2, d_n = -3, d_nb = -4, d_nm = -5, d_nc = -6, d_nv = -7, d_ny = -8, d_nf = -9, d_vk = -10,
       d_w1 = -11, d_w2 = -12, d_g = -13, d_world = -14, d_lin = -15, d_fixed = -16, d_mx = -17, d_mT = -18,
       d_ports = -19, d_springs = -20, d_NE = -21, d_fields = -22, d_ncv = -23, d_mx3 = -24, d_row = -25,
       d_int = -26, d_be = -27, d_bnd = -28, d_el = -29, d_nd = -30 };

static long long dim_value(const ffrf_dims *d, int code)
{
    switch (code) {
    case d_N: return d->N;
    case d_E: return d->E;
    case d_n: return d->n;
    case d_nb: return d->nb;
    case d_nm: return d->nm;
    case d_nc: return d->nc;
    case d_nv: return d->nv;
    case d_ny: return d->ny;
    case d_nf: return d->nf;
    case d_vk: return d->n_vk;
    case d_w1: return d->n_w1;
    case d_w2: return d->n_w2;
    case d_g: return d->n_g;
    case d_world: return d->n_world;
    case d_lin: return d->n_lin;
    case d_fixed: return d->n_fixed;
    case d_mx: return d->n_mx;
    case d_mT: return d->n_mT;
    case d_ports: return d->n_ports;
    case d_springs: return d->n_springs;
    case d_NE: return (long long)d->N + d->E;
    case d_fields: return d->n_fields;
    case d_ncv: return (long long)d->nc + d->nv;
    case d_mx3: return 3LL * d->n_mx;
    case d_row: return (long long)FFRF_OUTPUT_WIDTH * d->n_ports + FFRF_N_ENERGIES + 1;
    case d_int: return d->n_int;
    case d_be: return d->n_be;
    case d_bnd: return d->n_bnd;
    case d_el: return d->n_el;
    case d_nd: return d->n_el ? d->n : 0;
    default: return code;
    }
}

/* A named array of the body: where its pointer lives, its kind and shape. */
typedef struct {
    const char *name;
    char kind;        /* 'd' double, 'q' int64, 'i' int */
    size_t offset;    /* of the pointer field in struct ffrf_body */
    int shape[MAX_DIMS + 1]; /* dimension codes, ended by 0 (a scalar has none) */
} array_spec;

#define AT(field) offsetof(struct ffrf_body, field)
#define S(...) { __VA_ARGS__, 0 }

/* the reduced data and maps, read from the image (constant) */
static const array_spec DATA[] = {
    {"K", 'd', AT(data.K), S(d_E, d_n, d_n)},
    {"M", 'd', AT(data.M), S(d_E, d_n, d_n)},
    {"G", 'd', AT(data.G), S(d_E, 3, d_g, d_g)},
    {"W1", 'd', AT(data.W1), S(d_E, d_w1, 3, 3)},
    {"W2", 'd', AT(data.W2), S(d_E, d_w2, d_w2, 3, 3)},
    {"vk_a", 'd', AT(data.vk_a), S(d_E, d_vk, d_n)},
    {"vk_B", 'd', AT(data.vk_B), S(d_E, d_vk, d_n, d_n)},
    {"mass", 'd', AT(data.mass), S(d_E)},
    {"J0", 'd', AT(data.J0), S(d_E, 3, 3)},
    {"X_B", 'd', AT(data.X_B), S(d_E, d_nb, 3)},
    {"se_nodes", 'q', AT(data.se_nodes), S(d_E, d_nb)},
    {"cfg_map", 'q', AT(data.cfg_map), S(d_E, d_nc)},
    {"vel_map", 'q', AT(data.vel_map), S(d_E, d_nv)},
    {"gravity", 'd', AT(data.gravity), S(3)},
    {"rot_slots", 'q', AT(data.rot_slots), S(d_NE, 3)},
    {"newton_idx", 'q', AT(data.newton_idx), S(d_nf)},
    {"newton_pos", 'q', AT(data.newton_pos), S(d_ny)},
    {"field_of", 'q', AT(data.field_of), S(d_nf)},
    {"world_idx", 'q', AT(data.world_idx), S(d_world, 3)},
    {"lin_slots", 'q', AT(data.lin_slots), S(d_lin)},
    {"fixed_idx", 'q', AT(data.fixed_idx), S(d_fixed)},
    {"motion_x", 'q', AT(data.motion_x), S(d_mx)},
    {"motion_x_slots", 'q', AT(data.motion_x_slots), S(d_mx3)},
    {"motion_T_slots", 'q', AT(data.motion_T_slots), S(d_mT)},
    {"stage_mask", 'd', AT(data.stage_mask), S(d_ny)},
    {"motion_parts", 'd', AT(data.motion_parts), S(d_N, 2, 3)},
    {"port_node", 'q', AT(data.port_node), S(d_ports)},
    {"port_mode", 'q', AT(data.port_mode), S(d_ports, 2)},
    {"port_spring", 'q', AT(data.port_spring), S(d_ports)},
    {"spring_node", 'q', AT(data.spring_node), S(d_springs)},
    {"spring_trans", 'q', AT(data.spring_trans), S(d_springs)},
    {"spring_rot", 'q', AT(data.spring_rot), S(d_springs)},
    {"damp_MPhi", 'd', AT(data.damp_MPhi), S(d_E, d_n, d_el)},
    {"damp_omega", 'd', AT(data.damp_omega), S(d_E, d_el)},
};

/* the body's own arrays, allocated at creation */
static const array_spec OWN[] = {
    /* state (BodySystem._STATE_FIELDS) */
    {"xN", 'd', AT(state.xN), S(d_N, 3)},
    {"RN", 'd', AT(state.RN), S(d_N, 3, 3)},
    {"x0", 'd', AT(state.x0), S(d_E, 3)},
    {"R0", 'd', AT(state.R0), S(d_E, 3, 3)},
    {"eta", 'd', AT(state.eta), S(d_E, d_nm)},
    {"v", 'd', AT(state.v), S(d_E, d_nv)},
    {"yd", 'd', AT(state.yd), S(d_ny)},
    {"yd_prev", 'd', AT(state.yd_prev), S(d_ny)},
    {"yd_prev2", 'd', AT(state.yd_prev2), S(d_ny)},
    {"a", 'd', AT(state.a), S(d_ny)},
    {"fN", 'd', AT(state.fN), S(d_N, 3)},
    {"tN", 'd', AT(state.tN), S(d_N, 3)},
    {"energy", 'd', AT(state.energy), S(2)},
    /* inputs of a step */
    {"xN_p", 'd', AT(in.xN_p), S(d_N, 3)},
    {"RN_p", 'd', AT(in.RN_p), S(d_N, 3, 3)},
    {"zN_p", 'd', AT(in.zN_p), S(d_N, 6)},
    {"f_in", 'd', AT(in.f_in), S(d_N, 3)},
    {"t_in", 'd', AT(in.t_in), S(d_N, 3)},
    /* compliant ports */
    {"KC", 'd', AT(springs.KC), S(d_springs, 4, 3)},
    {"r_in", 'd', AT(springs.r_in), S(d_springs, 3)},
    {"v_in", 'd', AT(springs.v_in), S(d_springs, 3)},
    {"R_in", 'd', AT(springs.R_in), S(d_springs, 3, 3)},
    {"w_in", 'd', AT(springs.w_in), S(d_springs, 3)},
    {"spring_loads", 'd', AT(springs.loads), S(d_N, 2, 3)},
    /* structural damping (settable ratios and coefficients, the matrices they make) */
    {"damp_zeta", 'd', AT(damping.zeta), S(d_el)},
    {"damp_ab", 'd', AT(damping.ab), S(2)},
    {"damp_D", 'd', AT(damping.D), S(d_E, d_nd, d_nd)},
    /* an FMU's point values: its inputs as set at t_c */
    {"point_values", 'd', AT(point_values), S(d_ports, FFRF_POINT_WIDTH)},
    /* the factorization */
    {"luT", 'd', AT(lu.luT), S(d_nf, d_nf)},
    {"piv", 'i', AT(lu.piv), S(d_nf)},
    {"lu_meta", 'd', AT(lu.meta), S(12)},
    {"JT", 'd', AT(lu.JT), S(d_nf, d_nf)},
    /* the partition of the Newton unknowns (factor.c) */
    {"se_unknowns", 'q', AT(part.se_unknowns), S(d_E, d_int)},
    {"se_bnd", 'q', AT(part.se_bnd), S(d_E, d_be)},
    {"node_unknowns", 'q', AT(part.node_unknowns), S(d_bnd)},
    {"se_fb", 'q', AT(part.se_fb), S(d_E, d_be)},
    {"se_m", 'q', AT(part.se_m), S(d_E)},
    {"factor_y", 'd', AT(part.y), S(d_int)},
    {"factor_xB", 'd', AT(part.xB), S(d_bnd)},
    {"factor_u", 'd', AT(part.u), S(d_n)},
    {"factor_t", 'd', AT(part.t), S(d_int)},
    /* work */
    {"ydw", 'd', AT(work.ydw), S(d_ny)},
    {"p", 'd', AT(work.p), S(d_ny)},
    {"R", 'd', AT(work.R), S(d_NE, 3, 3)},
    {"F", 'd', AT(work.F), S(d_ny)},
    {"A0", 'd', AT(work.A0), S(d_ny)},
    {"P0", 'd', AT(work.P0), S(d_ny)},
    {"c", 'd', AT(work.c), S(d_ny)},
    {"Rn", 'd', AT(work.Rn), S(d_NE, 3, 3)},
    {"theta", 'd', AT(work.theta), S(d_NE, 3)},
    {"T", 'd', AT(work.T), S(d_NE, 3, 3)},
    {"Fl", 'd', AT(work.Fl), S(d_ncv)},
    {"Fz", 'd', AT(work.Fz), S(d_ncv, d_ncv)},
    {"Fy", 'd', AT(work.Fy), S(d_ncv, d_ncv)},
    {"b", 'd', AT(work.b), S(d_nf)},
    {"S", 'd', AT(work.S), S(d_fields)},
    {"row", 'd', AT(work.row), S(d_row)},
    {"q_rec", 'd', AT(work.q_rec), S(d_n)},
    {"M_luT", 'd', AT(work.M_luT), S(d_E, d_n, d_n)},
    {"M_piv", 'i', AT(work.M_piv), S(d_E, d_n)},
    {"M_inv", 'd', AT(work.M_inv), S(d_E, d_n, d_n)},
    {"MG", 'd', AT(work.MG), S(d_E, 3, d_g, d_g)},
    {"acc", 'd', AT(work.acc), S(3, d_n)},
};

#define COUNT(a) (sizeof(a) / sizeof((a)[0]))

/* work.MG = M_bar^-1 G_k of each superelement (M_inv's columns times G_k's), for the refresh's k_q rows
 * (superelement.c `jacobian`, solved); with no Coriolis term (n_g < n, or the term set without it) unused and left
 * zero. */
static void mass_solved_coriolis(ffrf_body *b)
{
    const int n = b->dims.n, ng = b->dims.n_g;
    if (ng != n || !(b->data.gyro & FFRF_CORIOLIS))
        return;
    for (int e = 0; e < b->dims.E; e++) {
        const double *inv = b->work.M_inv + (size_t)e * n * n; /* column m of M_bar^-1 in row m */
        for (int k = 0; k < 3; k++) {
            const double *G = b->data.G + ((size_t)e * 3 + k) * n * n;
            double *MG = b->work.MG + ((size_t)e * 3 + k) * n * n;
            for (int i = 0; i < n; i++)
                for (int j = 0; j < n; j++) {
                    double s = 0.0;
                    for (int m = 0; m < n; m++)
                        s += inv[(size_t)m * n + i] * G[(size_t)m * n + j];
                    MG[(size_t)i * n + j] = s;
                }
        }
    }
}

static long long spec_count(const ffrf_dims *d, const array_spec *s)
{
    long long c = 1;
    for (int i = 0; s->shape[i]; i++)
        c *= dim_value(d, s->shape[i]);
    return c;
}

static size_t kind_bytes(char kind)
{
    return kind == 'i' ? sizeof(int) : 8;
}

static void **field(ffrf_body *b, const array_spec *s)
{
    return (void **)((char *)b + s->offset);
}

/* ------------------------------------------------------------------ scalars of the image */

static int scalar(const entries *es, const char *name, double *out, char *err, size_t len)
{
    const entry *e = find(es, name);
    if (!e || e->count != 1)
        return fail(err, len, "body image: scalar %s missing%lld%lld", name, 0, 0);
    if (e->kind == 'd')
        memcpy(out, e->values, 8);
    else {
        int64_t v;
        memcpy(&v, e->values, 8);
        *out = (double)v;
    }
    return 0;
}

static int dim_of(const entries *es, const char *name, int axis, int *out, char *err, size_t len)
{
    const entry *e = find(es, name);
    if (!e || e->ndim <= axis)
        return fail(err, len, "body image: array %s missing or of too few dimensions (axis %lld)%lld", name, axis, 0);
    *out = (int)e->dims[axis];
    return 0;
}

static int dims_of(const entries *es, ffrf_dims *d, char *err, size_t len)
{
    if (dim_of(es, "mass", 0, &d->E, err, len) || dim_of(es, "K", 1, &d->n, err, len) ||
        dim_of(es, "X_B", 1, &d->nb, err, len) || dim_of(es, "motion_parts", 0, &d->N, err, len) ||
        dim_of(es, "cfg_map", 1, &d->nc, err, len) || dim_of(es, "vel_map", 1, &d->nv, err, len) ||
        dim_of(es, "stage_mask", 0, &d->ny, err, len) || dim_of(es, "newton_idx", 0, &d->nf, err, len) ||
        dim_of(es, "vk_a", 1, &d->n_vk, err, len) || dim_of(es, "W1", 1, &d->n_w1, err, len) ||
        dim_of(es, "W2", 1, &d->n_w2, err, len) || dim_of(es, "G", 2, &d->n_g, err, len) ||
        dim_of(es, "world_idx", 0, &d->n_world, err, len) || dim_of(es, "lin_slots", 0, &d->n_lin, err, len) ||
        dim_of(es, "fixed_idx", 0, &d->n_fixed, err, len) || dim_of(es, "motion_x", 0, &d->n_mx, err, len) ||
        dim_of(es, "motion_T_slots", 0, &d->n_mT, err, len) || dim_of(es, "port_node", 0, &d->n_ports, err, len) ||
        dim_of(es, "spring_node", 0, &d->n_springs, err, len) || dim_of(es, "damp_omega", 1, &d->n_el, err, len))
        return -1;
    d->nm = d->n - 6 * d->nb;
    d->n_loads = 0;
    d->n_int = 6 + d->nm + d->nv;
    d->n_be = 6 * d->nb;
    d->n_bnd = d->nf - d->E * d->n_int;
    if (d->E < 1 || d->nb < 1 || d->nm < 0 || d->nc != 6 + d->nm + 6 * d->nb || d->nv != 6 + d->n ||
        d->ny != 6 * d->N + d->E * (6 + d->nm) + d->E * d->nv || d->nf > d->ny || d->n_lin != 3 * d->N + 3 * d->E +
        d->E * d->nm + d->E * d->nv || d->n_bnd < 0 || d->nb > 64 /* factor.c's boundary lists */ ||
        (d->n_el && d->n_el != d->n) /* the damping basis: every mode of a superelement's reduced model */)
        return fail(err, len, "%sbody image: inconsistent sizes (E %lld, n %lld, ...)", "", d->E, d->n);
    return 0;
}

/* every index array within its range, so that no image can make a step read outside the body */
static int check_indices(const ffrf_body *b, char *err, size_t len)
{
    const ffrf_dims *d = &b->dims;
    const ffrf_data *D = &b->data;
    struct { const char *name; const idx_t *a; long long count, lo, hi; } checks[] = {
        {"se_nodes", D->se_nodes, (long long)d->E * d->nb, 0, d->N},
        {"cfg_map", D->cfg_map, (long long)d->E * d->nc, 0, d->ny},
        {"vel_map", D->vel_map, (long long)d->E * d->nv, 0, d->ny},
        {"rot_slots", D->rot_slots, 3LL * (d->N + d->E), 0, d->ny},
        {"newton_idx", D->newton_idx, d->nf, 0, d->ny},
        {"newton_pos", D->newton_pos, d->ny, 0, d->nf + 1},
        {"field_of", D->field_of, d->nf, 0, 64},
        {"world_idx", D->world_idx, 3LL * d->n_world, 0, d->ny},
        {"lin_slots", D->lin_slots, d->n_lin, 0, d->ny},
        {"fixed_idx", D->fixed_idx, d->n_fixed, 0, d->ny},
        {"motion_x", D->motion_x, d->n_mx, 0, d->N},
        {"motion_x_slots", D->motion_x_slots, 3LL * d->n_mx, 0, d->ny},
        {"motion_T_slots", D->motion_T_slots, d->n_mT, 0, d->ny},
        {"port_node", D->port_node, d->n_ports, 0, d->N},
        {"port_mode", D->port_mode, 2LL * d->n_ports, 0, 3},
        {"port_spring", D->port_spring, d->n_ports, -1, d->n_springs},
        {"spring_node", D->spring_node, d->n_springs, 0, d->N},
        {"spring_trans", D->spring_trans, d->n_springs, 0, 2},
        {"spring_rot", D->spring_rot, d->n_springs, 0, 2},
    };
    for (size_t c = 0; c < COUNT(checks); c++)
        for (long long i = 0; i < checks[c].count; i++)
            if (checks[c].a[i] < checks[c].lo || checks[c].a[i] >= checks[c].hi)
                return fail(err, len, "body image: index array %s has %lld out of its range (0 .. %lld)",
                            checks[c].name, (long long)checks[c].a[i], checks[c].hi - 1);
    if (b->data.k3 < 0 || b->data.k3 > d->nf || b->data.k3 % 3)
        return fail(err, len, "%sbody image: k3 = %lld is not a multiple of 3 within the %lld unknowns", "", b->data.k3, d->nf);
    return 0;
}

/* Which Newton unknowns are each superelement's own (its CM frame, modal and velocity rates: every one
 * free) and which are the boundary nodes' (factor.c); every Newton position belongs to exactly one. */
static int partition(ffrf_body *b, char *err, size_t len)
{
    const ffrf_dims *d = &b->dims;
    const ffrf_data *D = &b->data;
    ffrf_partition *P = &b->part;
    idx_t *owner = calloc((size_t)d->nf + 1, sizeof(idx_t)); /* 0 none, e + 1 internal of e, -1 node */
    idx_t *node_index = calloc((size_t)d->nf + 1, sizeof(idx_t));
    int status = 0;
    if (!owner || !node_index) {
        status = fail(err, len, "%sout of memory%lld%lld", "", 0, 0);
        goto done;
    }
    for (int e = 0; e < d->E && !status; e++)
        for (int i = 0; i < d->n_int; i++) {
            idx_t g = i < 6 + d->nm ? D->cfg_map[(size_t)e * d->nc + i] : D->vel_map[(size_t)e * d->nv + i - 6 - d->nm];
            idx_t p = D->newton_pos[g];
            if (p >= d->nf || owner[p]) {
                status = fail(err, len, "%sbody image: superelement %lld has a rate that is not its own unknown (rate %lld)",
                              "", e, g);
                break;
            }
            owner[p] = e + 1;
            P->se_unknowns[(size_t)e * d->n_int + i] = p;
        }
    int k = 0;
    for (int p = 0; p < d->nf && !status; p++)
        if (!owner[p]) {
            if (k == d->n_bnd) {
                status = fail(err, len, "%sbody image: more node unknowns than %lld%lld", "", d->n_bnd, 0);
                break;
            }
            node_index[p] = k;
            P->node_unknowns[k++] = p;
        }
    for (int e = 0; e < d->E && !status; e++)
        for (int i = 0; i < d->n_be; i++) {
            idx_t g = 6 * D->se_nodes[(size_t)e * d->nb + i / 6] + i % 6, p = D->newton_pos[g];
            if (p < d->nf && owner[p]) {
                status = fail(err, len, "%sbody image: boundary rate %lld of superelement %lld is another's own", "", g, e);
                break;
            }
            P->se_bnd[(size_t)e * d->n_be + i] = p < d->nf ? node_index[p] : -1;
        }
done:
    free(owner);
    free(node_index);
    return status;
}

/* ------------------------------------------------------------------ create, free */

static void reset_state(ffrf_body *b, const entries *es)
{
    const ffrf_dims *d = &b->dims;
    const entry *xN = find(es, "xN"), *x0 = find(es, "x0"), *KC = find(es, "KC");
    memset(b->state.eta, 0, sizeof(double) * d->E * d->nm);
    memcpy(b->state.xN, xN->values, sizeof(double) * 3 * d->N);
    memcpy(b->state.x0, x0->values, sizeof(double) * 3 * d->E);
    for (int k = 0; k < d->N + d->E; k++) {
        double *R = k < d->N ? b->state.RN + 9 * k : b->state.R0 + 9 * (k - d->N);
        for (int i = 0; i < 9; i++)
            R[i] = i % 4 == 0 ? 1.0 : 0.0;
    }
    if (KC)
        memcpy(b->springs.KC, KC->values, sizeof(double) * 12 * d->n_springs);
}

ffrf_body *ffrf_body_create(const void *image, size_t size, char *err, size_t err_len)
{
    if (err && err_len)
        err[0] = '\0';
    if (!image)
        return fail(err, err_len, "%sno body image given%lld%lld", "", 0, 0), NULL;
    ffrf_body *b = calloc(1, sizeof(*b));
    entries *es = calloc(1, sizeof(*es));
    unsigned char *copy = NULL;
    if (!b || !es) {
        free(b);
        free(es);
        return fail(err, err_len, "%sout of memory%lld%lld", "", 0, 0), NULL;
    }
    if (parse(image, size, &copy, es, err, err_len) || dims_of(es, &b->dims, err, err_len))
        goto failed;
    b->image = copy;
    ffrf_dims *d = &b->dims;
    /* the constant arrays: point into the copy after checking their shapes */
    for (size_t i = 0; i < COUNT(DATA); i++) {
        const array_spec *s = &DATA[i];
        const entry *e = find(es, s->name);
        if (!e) {
            fail(err, err_len, "body image: array %s missing%lld%lld", s->name, 0, 0);
            goto failed;
        }
        if (e->kind != s->kind || (long long)e->count != spec_count(d, s)) {
            fail(err, err_len, "body image: array %s has %lld values, its shape needs %lld", s->name, (long long)e->count,
                 spec_count(d, s));
            goto failed;
        }
        *field(b, s) = (void *)e->values;
    }
    for (int i = 0; i < d->nf; i++)
        if (b->data.field_of[i] + 1 > d->n_fields)
            d->n_fields = (int)b->data.field_of[i] + 1;
    double v;
#define SCALAR(name, target) \
    if (scalar(es, name, &v, err, err_len)) \
        goto failed; \
    target = v
    SCALAR("gyro", b->data.gyro);
    SCALAR("stiff", b->data.stiff);
    SCALAR("k3", b->data.k3);
    SCALAR("theta_refresh", b->data.theta_refresh);
    SCALAR("kept_accept", b->data.kept_accept);
    SCALAR("kept_radius", b->data.kept_radius);
    SCALAR("keep_miss", b->data.keep_miss);
    SCALAR("wide_miss", b->data.wide_miss);
    SCALAR("kept_age", b->data.kept_age);
    SCALAR("near_miss", b->data.near_miss);
    SCALAR("near_contraction", b->data.near_contraction);
    SCALAR("refresh_min", b->data.refresh_min);
    SCALAR("refresh_max", b->data.refresh_max);
    SCALAR("tol", b->tol);
    SCALAR("max_iter", b->max_iter);
    SCALAR("rho_inf", b->rho_inf);
    SCALAR("am", b->am);
    SCALAR("af", b->af);
    SCALAR("gamma", b->gamma);
#undef SCALAR
    if (check_indices(b, err, err_len))
        goto failed;
    {
        const entry *xN = find(es, "xN"), *x0 = find(es, "x0"), *KC = find(es, "KC");
        const entry *zeta = find(es, "damp_zeta"), *ab = find(es, "damp_ab");
        if (!xN || xN->count != 3ULL * d->N || !x0 || x0->count != 3ULL * d->E ||
            (KC && KC->count != 12ULL * d->n_springs) || (!KC && d->n_springs)) {
            fail(err, err_len, "%sbody image: reference state (xN, x0) or compliances (KC) missing or misshapen%lld%lld",
                 "", 0, 0);
            goto failed;
        }
        if (!zeta || zeta->kind != 'd' || zeta->count != (uint64_t)d->n_el || !ab || ab->kind != 'd' || ab->count != 2) {
            fail(err, err_len, "%sbody image: damping (damp_zeta [%lld], damp_ab [2]) missing or misshapen%lld", "",
                 d->n_el, 0);
            goto failed;
        }
    }
    /* one allocation for every array of the body's own, 16-byte aligned each */
    size_t total = 0, se_bytes = ffrf_se_work_bytes(d);
    for (size_t i = 0; i < COUNT(OWN); i++)
        total += (kind_bytes(OWN[i].kind) * (size_t)spec_count(d, &OWN[i]) + 15) / 16 * 16 + REDZONE;
    total += (se_bytes + 15) / 16 * 16;
    b->arena = calloc(1, total ? total : 16);
    if (!b->arena) {
        fail(err, err_len, "%sout of memory (%lld bytes for the body's arrays)%lld", "", (long long)total, 0);
        goto failed;
    }
    char *at = b->arena;
    for (size_t i = 0; i < COUNT(OWN); i++) {
        size_t bytes = kind_bytes(OWN[i].kind) * (size_t)spec_count(d, &OWN[i]), span = (bytes + 15) / 16 * 16 + REDZONE;
        *field(b, &OWN[i]) = at;
        POISON(at + bytes, span - bytes);
        at += span;
    }
    b->work.se = ffrf_se_work_bind(at, d);
    if (partition(b, err, err_len))
        goto failed;
    ffrf_factor_prepare(b); /* factor.c: each superelement's free boundary dofs, the store's size */
    if (ffrf_mass_factors(b)) {
        fail(err, err_len, "%sbody image: a superelement's mass matrix M_bar is singular%lld%lld", "", 0, 0);
        goto failed;
    }
    mass_solved_coriolis(b);
    reset_state(b, es);
    memcpy(b->damping.zeta, find(es, "damp_zeta")->values, sizeof(double) * (size_t)d->n_el);
    memcpy(b->damping.ab, find(es, "damp_ab")->values, sizeof(double) * 2);
    if (ffrf_damping_update(b)) {
        fail(err, err_len, "%sbody image: a damping ratio or Rayleigh coefficient is negative or not finite%lld%lld", "",
             0, 0);
        goto failed;
    }
    free(es);
    return b;
failed:
    free(es);
    if (!b->image)
        free(copy);
    ffrf_body_free(b);
    return NULL;
}

void ffrf_body_free(ffrf_body *b)
{
    if (!b)
        return;
    free(b->arena);
    free(b->image);
    free(b);
}

/* ------------------------------------------------------------------ statuses */

/* the numpy path's messages of a failed step (runtime/native/binding.py `failure`, integrator.py) */
const char *ffrf_status_text(int status)
{
    switch (status) {
    case FFRF_NOT_FINITE:
        return "the residual is not finite (NaN or overflow)";
    case FFRF_NOT_CONVERGED:
        return "Newton did not converge";
    case FFRF_NOT_FACTORED:
        return "iteration matrix cannot be factored (not finite or singular)";
    case FFRF_ROTATION_ALIAS:
        return "a rotation increment over the step exceeds pi (step too large for the motion, or an absurd input)";
    case FFRF_BAD_STEP:
        return "step size must be positive and finite";
    case FFRF_ITERATION_CAP:
        return "Newton did not converge within the iteration cap (max_newton_iterations)";
    default:
        return "step failed";
    }
}

/* ------------------------------------------------------------------ structural damping */

int ffrf_damping_update(ffrf_body *b)
{
    const ffrf_dims *d = &b->dims;
    const int n = d->n, ne = d->n_el;
    const double alpha = b->damping.ab[0], beta = b->damping.ab[1];
    /* !(x >= 0) also refuses NaN */
    if (!(alpha >= 0.0 && alpha <= 1e300) || !(beta >= 0.0 && beta <= 1e300))
        return -1;
    for (int i = 0; i < ne; i++)
        if (!(b->damping.zeta[i] >= 0.0 && b->damping.zeta[i] <= 1e300))
            return -1;
    if (ne == 0 && (alpha > 0.0 || beta > 0.0))
        return -1; /* no damping basis in the image: nothing to damp with */
    int on = 0;
    for (int e = 0; e < d->E && ne; e++) {
        const double (*MPhi)[ne] = (const double (*)[ne])b->data.damp_MPhi + (size_t)e * n;
        const double *w = b->data.damp_omega + (size_t)e * ne;
        double (*D)[n] = (double (*)[n])b->damping.D + (size_t)e * n;
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n; j++) {
                double s = 0.0;
                for (int k = 0; k < ne; k++) /* c_k = 2 zeta_k omega_k + alpha + beta omega_k^2 (damping.py) */
                    s += MPhi[i][k] * (2.0 * b->damping.zeta[k] * w[k] + alpha + beta * w[k] * w[k]) * MPhi[j][k];
                D[i][j] = s;
                on |= s != 0.0;
            }
    }
    b->damping.on = on;
    return 0;
}

/* ------------------------------------------------------------------ named access */

void *ffrf_body_array(ffrf_body *b, const char *name, size_t *count, char *kind)
{
    const array_spec *tables[2] = {DATA, OWN};
    const size_t sizes[2] = {COUNT(DATA), COUNT(OWN)};
    for (int t = 0; t < 2; t++)
        for (size_t i = 0; i < sizes[t]; i++)
            if (strcmp(tables[t][i].name, name) == 0) {
                if (count)
                    *count = (size_t)spec_count(&b->dims, &tables[t][i]);
                if (kind)
                    *kind = tables[t][i].kind;
                return *field(b, &tables[t][i]);
            }
    return NULL;
}

int ffrf_body_get_scalar(const ffrf_body *b, const char *name, double *value)
{
    const ffrf_dims *d = &b->dims;
    struct { const char *name; double value; } s[] = {
        {"t", b->state.t}, {"iterations", b->state.iterations}, {"tol", b->tol}, {"max_iter", b->max_iter},
        {"iteration_cap", b->iteration_cap},
        {"rho_inf", b->rho_inf}, {"am", b->am}, {"af", b->af}, {"gamma", b->gamma},
        {"lu_version", (double)b->lu.version}, {"refreshed", (double)b->lu.refreshed}, {"N", d->N}, {"E", d->E},
        {"n", d->n}, {"nb", d->nb}, {"nm", d->nm},
        {"ny", d->ny}, {"nf", d->nf}, {"n_ports", d->n_ports}, {"n_springs", d->n_springs},
    };
    for (size_t i = 0; i < COUNT(s); i++)
        if (strcmp(s[i].name, name) == 0) {
            *value = s[i].value;
            return 0;
        }
    return -1;
}

int ffrf_body_set_scalar(ffrf_body *b, const char *name, double value)
{
    if (strcmp(name, "t") == 0)
        b->state.t = value;
    else if (strcmp(name, "iterations") == 0)
        b->state.iterations = (int)value;
    else if (strcmp(name, "tol") == 0)
        b->tol = value;
    else if (strcmp(name, "max_iter") == 0)
        b->max_iter = (int)value;
    else if (strcmp(name, "iteration_cap") == 0)
        b->iteration_cap = (int)value;
    else if (strcmp(name, "am") == 0)
        b->am = value;
    else if (strcmp(name, "af") == 0)
        b->af = value;
    else if (strcmp(name, "gamma") == 0)
        b->gamma = value;
    else
        return -1;
    return 0;
}

void ffrf_body_set_schedule(ffrf_body *b, double *r0, idx_t *kind, double *prm, double *axis, idx_t *load_port,
                            double *load_window, double *load_fm, int n_loads)
{
    b->schedule.r0 = r0;
    b->schedule.kind = kind;
    b->schedule.prm = prm;
    b->schedule.axis = axis;
    b->schedule.load_port = load_port;
    b->schedule.load_window = load_window;
    b->schedule.load_fm = load_fm;
    b->dims.n_loads = n_loads;
}

/* ------------------------------------------------------------------ state */

/* the state vector: t, iterations, energy (2), the state arrays in BodySystem._STATE_FIELDS' order,
 * lu_meta (12), luT (nf nf), piv (nf) */
static const char *const STATE_ARRAYS[] = {"xN", "RN", "x0", "R0", "eta", "v", "yd", "yd_prev", "yd_prev2", "a", "fN", "tN"};

size_t ffrf_body_state_size(const ffrf_body *b)
{
    size_t n = 4 + 12 + (size_t)b->dims.nf * b->dims.nf + (size_t)b->dims.nf, count;
    for (size_t i = 0; i < COUNT(STATE_ARRAYS); i++) {
        ffrf_body_array((ffrf_body *)b, STATE_ARRAYS[i], &count, NULL);
        n += count;
    }
    return n;
}

void ffrf_body_get_state(const ffrf_body *b, double *out)
{
    size_t count, nf = (size_t)b->dims.nf;
    *out++ = b->state.t;
    *out++ = b->state.iterations;
    *out++ = b->state.energy[0];
    *out++ = b->state.energy[1];
    for (size_t i = 0; i < COUNT(STATE_ARRAYS); i++) {
        const double *a = ffrf_body_array((ffrf_body *)b, STATE_ARRAYS[i], &count, NULL);
        memcpy(out, a, sizeof(double) * count);
        out += count;
    }
    memcpy(out, b->lu.meta, sizeof(double) * 12);
    out += 12;
    memcpy(out, b->lu.luT, sizeof(double) * nf * nf);
    out += nf * nf;
    for (size_t i = 0; i < nf; i++)
        *out++ = b->lu.piv[i];
}

int ffrf_body_set_state(ffrf_body *b, const double *in, size_t size)
{
    size_t count, nf = (size_t)b->dims.nf;
    if (size != ffrf_body_state_size(b))
        return -1;
    const double *piv = in + size - nf, *meta = piv - nf * nf - 12;
    /* a pivot out of range would make a solve write outside the body: factor.c's pivots are local to their
     * block (E blocks of n_int for the superelements' own unknowns, of which the first 6 + nm are used and the
     * rest is j, then one of n_bnd), each pivot j of a used block of n in [j, n) */
    for (size_t i = 0; i < nf && meta[0] != 0.0; i++) {
        size_t block = (size_t)b->dims.E * (size_t)b->dims.n_int, nz = (size_t)(6 + b->dims.nm);
        size_t j = i < block ? i % (size_t)b->dims.n_int : i - block;
        size_t n = i < block ? (j < nz ? nz : j + 1) : (size_t)b->dims.n_bnd;
        if (!(piv[i] >= (double)j && piv[i] < (double)n) || piv[i] != (double)(int)piv[i])
            return -2;
    }
    if (!(in[1] >= 0.0 && in[1] < 1e9))
        return -2;
    b->state.t = *in++;
    b->state.iterations = (int)*in++;
    b->state.energy[0] = *in++;
    b->state.energy[1] = *in++;
    for (size_t i = 0; i < COUNT(STATE_ARRAYS); i++) {
        double *a = ffrf_body_array(b, STATE_ARRAYS[i], &count, NULL);
        memcpy(a, in, sizeof(double) * count);
        in += count;
    }
    memcpy(b->lu.meta, in, sizeof(double) * 12);
    in += 12;
    memcpy(b->lu.luT, in, sizeof(double) * nf * nf);
    in += nf * nf;
    for (size_t i = 0; i < nf; i++)
        b->lu.piv[i] = b->lu.meta[0] != 0.0 ? (int)in[i] : (int)i;
    b->lu.version++;
    return 0;
}
