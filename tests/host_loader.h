/* Loading an FMU's binary in the C hosts (tests/fmi2_host.c, tests/fmi3_host.c, benchmarks/fmu_host_bench.c):
 * the library, a symbol of it (sym: one the host cannot run without) and its unloading, on Linux (dlopen; the path "-" is the host itself, for a build that links the FMU in) and
 * on Windows (LoadLibrary: the hosts cross-compiled by zig and run in wine, tests/test_native_win64.py,
 * tests/test_fmi3.py). Header-only, included once by each host; static inline, so that a host need not use
 * every function (-Wall -Werror). */
#ifndef HOST_LOADER_H
#define HOST_LOADER_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#if defined(_WIN32)
#include <windows.h>
static inline void *open_library(const char *path) { return (void *)LoadLibraryA(path); }
static inline void *symbol(void *lib, const char *name) { return (void *)GetProcAddress((HMODULE)lib, name); }
static inline int close_library(void *lib) { return !FreeLibrary((HMODULE)lib); } /* 0: unloaded */
static inline const char *library_error(void) { return "LoadLibrary failed"; }
#else
#include <dlfcn.h>
static inline void *open_library(const char *path)
{
    return strcmp(path, "-") ? dlopen(path, RTLD_NOW | RTLD_LOCAL) : dlopen(NULL, RTLD_NOW);
}
static inline void *symbol(void *lib, const char *name) { return dlsym(lib, name); }
static inline int close_library(void *lib) { return dlclose(lib); } /* 0: unloaded */
static inline const char *library_error(void) { return dlerror(); }
#endif

/* A symbol the host cannot run without: missing, the host ends with exit status 3 naming it. */
static inline void *sym(void *lib, const char *name)
{
    void *f = symbol(lib, name);
    if (!f) {
        fprintf(stderr, "missing %s\n", name);
        exit(3);
    }
    return f;
}

#endif
