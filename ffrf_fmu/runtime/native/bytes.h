/* Little-endian words of a binary file and their FNV-1a 64 checksum: the one reader of the runtime's body image
 * (body.c; runtime/native/image.py writes it) and of an FMU's resources/body.bin (fmu/native/resource.c;
 * fmu/native/resource.py writes it). The callers check the bounds before they read. Header-only. */
#ifndef FFRF_BYTES_H
#define FFRF_BYTES_H

#include <stddef.h>
#include <stdint.h>

static inline uint64_t ffrf_read_u64(const unsigned char *p)
{
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--)
        v = (v << 8) | p[i];
    return v;
}

static inline uint32_t ffrf_read_u32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* FNV-1a 64 over the n bytes' whole 8-byte little-endian words (image.py `checksum`, resource.py) */
static inline uint64_t ffrf_fnv1a_words(const unsigned char *p, size_t n)
{
    uint64_t h = 0xCBF29CE484222325ull;
    for (size_t i = 0; i + 8 <= n; i += 8)
        h = (h ^ ffrf_read_u64(p + i)) * 0x100000001B3ull;
    return h;
}

#endif
