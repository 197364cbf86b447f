/* resources/body.bin: where it is (the resource URI a host passes to fmi2Instantiate) and what it holds.
 *
 * Layout (little-endian; written by ffrf_fmu/fmu/native/resource.py, the one description of it):
 *   header   magic "FFRFFMU\0" | u32 format version (FMU_FORMAT_VERSION) | u32 runtime version
 *            (FFRF_RUNTIME_VERSION) | u64 payload bytes | u64 FNV-1a 64 checksum of the stored payload
 *            | u64 scrambling seed
 *   payload  scrambled (XOR with a splitmix64 key stream from the seed, one 64-bit word at a time), then
 *            sections: tag (8 bytes, NUL-padded) | u64 bytes | data padded to 8 bytes.
 * The scrambling keeps the reduced matrices out of plain sight (no file or string shows them); it is
 * not encryption: the key is in the file and the code is in the binary (docs/fmu.md says what a
 * determined partner can recover). */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bytes.h"
#include "resource.h"

#define HEADER_BYTES 40

static uint64_t splitmix64(uint64_t *s)
{
    uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

static int hexval(char c)
{
    if (c >= '0' && c <= '9')
        return c - '0';
    if (c >= 'a' && c <= 'f')
        return c - 'a' + 10;
    if (c >= 'A' && c <= 'F')
        return c - 'A' + 10;
    return -1;
}

/* The local path of a resource location (FMI 2.0: a URI; file:///abs, file:/abs, file://localhost/abs,
 * percent-escapes; a plain absolute path, which some hosts pass, is taken as is). 0, or -1 with why not. */
int fmu_resource_path(const char *uri, char *path, size_t len, char *err, size_t err_len)
{
    if (!uri || !*uri) {
        snprintf(err, err_len, "no resource location given (fmuResourceLocation is %s): the FMU needs its "
                 "resources folder", uri ? "empty" : "NULL");
        return -1;
    }
    const char *p = uri;
    if (strncmp(p, "file:", 5) == 0) {
        p += 5;
        if (strncmp(p, "//", 2) == 0) { /* an authority: empty or localhost */
            p += 2;
            const char *slash = strchr(p, '/');
            size_t host = slash ? (size_t)(slash - p) : strlen(p);
            if (host && !(host == 9 && strncmp(p, "localhost", 9) == 0)) {
                snprintf(err, err_len, "resource location %.300s names host %.*s: only local files (file:///path, "
                         "file:/path or file://localhost/path) can be read", uri, (int)(host > 100 ? 100 : host), p);
                return -1;
            }
            p += host;
        }
        if (*p != '/') {
            snprintf(err, err_len, "resource location %.300s is not an absolute file URI (file:///path)", uri);
            return -1;
        }
#if defined(_WIN32)
        if (p[1] && p[2] == ':') /* file:///C:/dir -> C:/dir */
            p++;
#endif
    } else if (strstr(p, "://")) {
        snprintf(err, err_len, "resource location %.300s: only file URIs are supported", uri);
        return -1;
    }
    size_t k = 0;
    for (; *p; p++) {
        char c = *p;
        if (c == '%') {
            int hi = hexval(p[1]), lo = hi < 0 ? -1 : hexval(p[2]);
            if (lo < 0) {
                snprintf(err, err_len, "resource location %.300s has a bad percent-escape", uri);
                return -1;
            }
            c = (char)(hi * 16 + lo);
            p += 2;
            if (c == 0) {
                snprintf(err, err_len, "resource location %.300s escapes a NUL character", uri);
                return -1;
            }
        }
        if (k + 1 >= len) {
            snprintf(err, err_len, "resource location %.300s is too long", uri);
            return -1;
        }
        path[k++] = c;
    }
    while (k > 1 && path[k - 1] == '/')
        k--;
    path[k] = 0;
    return 0;
}

typedef struct {
    const unsigned char *data;
    size_t size;
} section;

static int find(const unsigned char *pay, size_t size, const char *tag, section *out)
{
    size_t i = 0;
    while (i + 16 <= size) {
        uint64_t n = ffrf_read_u64(pay + i + 8);
        if (n > size - i - 16)
            return -1;
        if (strncmp((const char *)pay + i, tag, 8) == 0) {
            out->data = pay + i + 16;
            out->size = (size_t)n;
            return 0;
        }
        i += 16 + (size_t)((n + 7) / 8 * 8);
    }
    return -1;
}

static int need(const unsigned char *pay, size_t size, const char *tag, size_t bytes, section *out, char *err,
                size_t err_len)
{
    if (find(pay, size, tag, out) != 0 || (bytes != (size_t)-1 && out->size != bytes)) {
        snprintf(err, err_len, "resources/body.bin: section %s missing or of the wrong size", tag);
        return -1;
    }
    return 0;
}

static const char *string_at(const section *names, uint32_t off)
{
    if (off >= names->size || !memchr(names->data + off, 0, names->size - off))
        return NULL;
    return (const char *)names->data + off;
}

int fmu_description_load(fmu_description *d, const char *dir, char *err, size_t err_len)
{
    memset(d, 0, sizeof *d);
    char path[4200];
    snprintf(path, sizeof path, "%s/body.bin", dir);
    FILE *f = fopen(path, "rb");
    if (!f) {
        FILE *probe = fopen(dir, "rb");
        if (probe)
            fclose(probe);
        snprintf(err, err_len, "cannot open %.3000s (%s)%s", path, strerror(errno),
                 probe ? "" : ": the resources folder is missing or unreadable");
        return -1;
    }
    unsigned char head[HEADER_BYTES];
    if (fread(head, 1, HEADER_BYTES, f) != HEADER_BYTES || memcmp(head, "FFRFFMU\0", 8) != 0) {
        fclose(f);
        snprintf(err, err_len, "%.3000s is not an ffrf-fmu body resource (bad header)", path);
        return -1;
    }
    uint32_t format = ffrf_read_u32(head + 8), runtime = ffrf_read_u32(head + 12);
    uint64_t size = ffrf_read_u64(head + 16), check = ffrf_read_u64(head + 24), seed = ffrf_read_u64(head + 32);
    if (format != FMU_FORMAT_VERSION || runtime != FFRF_RUNTIME_VERSION) {
        fclose(f);
        snprintf(err, err_len, "%.3000s is of format %u for runtime %u; this binary reads format %d for runtime %d "
                 "(rebuild the FMU)", path, format, runtime, FMU_FORMAT_VERSION, FFRF_RUNTIME_VERSION);
        return -1;
    }
    if (size % 8 || size > ((uint64_t)1 << 34)) {
        fclose(f);
        snprintf(err, err_len, "%.3000s: implausible payload size %llu", path, (unsigned long long)size);
        return -1;
    }
    unsigned char *pay = malloc((size_t)size ? (size_t)size : 8);
    if (!pay) {
        fclose(f);
        snprintf(err, err_len, "out of memory reading %.3000s", path);
        return -1;
    }
    size_t got = fread(pay, 1, (size_t)size, f);
    int extra = fgetc(f) != EOF;
    fclose(f);
    if (got != size || extra || ffrf_fnv1a_words(pay, (size_t)size) != check) {
        free(pay);
        snprintf(err, err_len, "%.3000s is damaged (%s)", path, got != size ? "truncated" : extra ? "trailing bytes"
                 : "checksum mismatch");
        return -1;
    }
    for (size_t i = 0; i < size; i += 8) { /* descramble in place */
        uint64_t k = splitmix64(&seed), w = ffrf_read_u64(pay + i) ^ k;
        for (int j = 0; j < 8; j++)
            pay[i + j] = (unsigned char)(w >> (8 * j));
    }
    d->blob = pay;
    section s, names;
    size_t n = (size_t)size;
#define NEED(tag, bytes, out) if (need(pay, n, tag, bytes, out, err, err_len)) goto bad
    NEED("guid", (size_t)-1, &s);
    if (s.size == 0 || s.size >= sizeof d->guid || s.data[s.size - 1] != 0)
        goto bad_content;
    memcpy(d->guid, s.data, s.size);
    NEED("about", (size_t)-1, &s);
    snprintf(d->description, sizeof d->description, "%.*s", (int)(s.size ? s.size - 1 : 0), (const char *)s.data);
    NEED("names", (size_t)-1, &names);
    NEED("counts", 20, &s);
    const int32_t *counts = (const int32_t *)s.data;
    d->n_vars = counts[0];
    d->n_ports = counts[1];
    d->n_out = counts[2];
    d->n_probes = counts[3];
    d->n_modal = counts[4];
    if (d->n_vars <= 0 || d->n_ports < 0 || d->n_out < 0 || d->n_probes < 0 || d->n_vars > 1 << 24 ||
        d->n_ports > 1 << 16 || d->n_out > d->n_vars || d->n_probes > d->n_vars || d->n_modal < 0 ||
        d->n_modal > d->n_vars)
        goto bad_content;
    NEED("vars", (size_t)d->n_vars * 48, &s);
    d->vars = calloc((size_t)d->n_vars, sizeof *d->vars);
    d->ports = calloc((size_t)(d->n_ports ? d->n_ports : 1), sizeof *d->ports);
    if (!d->vars || !d->ports)
        goto bad_content;
    for (int i = 0; i < d->n_vars; i++) {
        const unsigned char *r = s.data + 48 * (size_t)i;
        const int32_t *iv = (const int32_t *)r;
        const double *dv = (const double *)(r + 24);
        fmu_variable *v = &d->vars[i];
        v->type = iv[0];
        v->causality = iv[1];
        v->dkind = iv[2];
        v->has_min = iv[3] & 1;
        v->has_max = (iv[3] >> 1) & 1;
        v->name = string_at(&names, (uint32_t)iv[4]);
        v->start = dv[0];
        v->min = dv[1];
        v->max = dv[2];
        if (!v->name || v->type < TYPE_REAL || v->type > TYPE_INTEGER || v->causality < CAUS_INPUT ||
            v->causality > CAUS_PARAMETER)
            goto bad_content;
    }
    NEED("ports", (size_t)d->n_ports * 16, &s);
    for (int i = 0; i < d->n_ports; i++) {
        const int32_t *iv = (const int32_t *)(s.data + 16 * (size_t)i);
        d->ports[i] = (fmu_port){string_at(&names, (uint32_t)iv[3]), iv[0], iv[1], iv[2]};
        if (!d->ports[i].name)
            goto bad_content;
    }
    NEED("pointvr", (size_t)d->n_ports * FFRF_POINT_WIDTH * 4, &s);
    d->point_vr = (const int32_t *)s.data;
    NEED("outvr", (size_t)d->n_out * 4, &s);
    d->out_vr = (const int32_t *)s.data;
    NEED("outsrc", (size_t)d->n_out * 4, &s);
    d->out_src = (const int32_t *)s.data;
    NEED("pseen", (size_t)d->n_probes * 4, &s);
    d->probe_seen = (const int32_t *)s.data;
    NEED("pframe", (size_t)d->n_probes * 4, &s);
    d->probe_frame = (const int32_t *)s.data;
    NEED("pdX", (size_t)d->n_probes * 24, &s);
    d->probe_dX = (const double *)s.data;
    NEED("params", 14 * 4, &s);
    {
        const int32_t *pv = (const int32_t *)s.data;
        d->vr_step = pv[0];
        d->vr_rho_inf = pv[1];
        d->vr_terms = pv[2];
        d->vr_iterations = pv[3];
        for (int i = 0; i < 3; i++) {
            d->vr_gravity[i] = pv[4 + i];
            d->vr_velocity[i] = pv[7 + i];
            d->vr_angular_velocity[i] = pv[10 + i];
        }
        d->vr_max_iterations = pv[13];
        for (int i = 0; i < 14; i++)
            if (pv[i] < 0 || pv[i] >= d->n_vars)
                goto bad_content;
    }
    NEED("disp", (size_t)d->n_ports * 12, &s);
    d->disp_vr = (const int32_t *)s.data;
    NEED("coupling", (size_t)d->n_ports * 48, &s);
    d->coupling_vr = (const int32_t *)s.data;
    NEED("damping", (size_t)-1, &s); /* alpha, beta, k, k ratios (int32 each) */
    {
        const int32_t *dv = (const int32_t *)s.data;
        if (s.size < 16 || s.size % 4)
            goto bad_content;
        d->vr_damp_alpha = dv[0];
        d->vr_damp_beta = dv[1];
        d->n_damp_ratios = dv[2];
        d->damp_ratio_vr = dv + 3;
        if (d->n_damp_ratios < 1 || (size_t)d->n_damp_ratios != s.size / 4 - 3)
            goto bad_content;
        for (int i = 0; i < 3 + d->n_damp_ratios; i++)
            if (i != 2 && (dv[i] < 0 || dv[i] >= d->n_vars))
                goto bad_content;
    }
    NEED("origin", 24, &s);
    memcpy(d->origin, s.data, 24);
    {
        const int32_t *lists[] = {d->point_vr, d->out_vr, d->disp_vr, d->coupling_vr};
        const size_t sizes[] = {(size_t)d->n_ports * FFRF_POINT_WIDTH, (size_t)d->n_out, (size_t)d->n_ports * 3,
                                (size_t)d->n_ports * 12};
        for (int l = 0; l < 4; l++)
            for (size_t i = 0; i < sizes[l]; i++)
                if (lists[l][i] < -1 || lists[l][i] >= d->n_vars)
                    goto bad_content;
        for (int i = 0; i < d->n_probes; i++)
            if (d->probe_seen[i] < 0 || d->probe_seen[i] >= d->n_ports || d->probe_frame[i] < 0 ||
                d->probe_frame[i] >= d->n_ports)
                goto bad_content;
        size_t n_src = (size_t)d->n_ports * FFRF_OUTPUT_WIDTH + FFRF_N_ENERGIES + 1 + 3 * (size_t)d->n_probes +
                       2 * (size_t)d->n_modal;
        for (int i = 0; i < d->n_out; i++)
            if (d->out_src[i] < 0 || (size_t)d->out_src[i] >= n_src || d->out_vr[i] < 0)
                goto bad_content;
    }
    for (int k = 0; k < FMU_TERM_SETS; k++) {
        char tag[8] = "image0";
        tag[5] = (char)('0' + k);
        if (find(pay, n, tag, &s) == 0) {
            d->image[k] = s.data;
            d->image_size[k] = s.size;
        }
    }
    if (!d->image[0] && !d->image[1] && !d->image[2])
        goto bad_content;
    for (int k = 0; k < FMU_TERM_SETS; k++) { /* optional: a scene that starts at its equilibrium */
        char tag[8] = "start0";
        tag[5] = (char)('0' + k);
        if (find(pay, n, tag, &s) == 0) {
            const double *v = (const double *)s.data;
            if (s.size % 8 || s.size < 32 || !d->image[k] || !(v[0] == 1.0 || v[0] == 2.0))
                goto bad_content;
            d->start[k] = v;
            d->start_count[k] = s.size / 8;
        }
    }
    return 0;
#undef NEED
bad_content:
    snprintf(err, err_len, "%.3000s: inconsistent content (a damaged or foreign resource)", path);
bad:
    fmu_description_free(d);
    return -1;
}

void fmu_description_free(fmu_description *d)
{
    free(d->vars);
    free(d->ports);
    free(d->blob);
    memset(d, 0, sizeof *d);
}
