/* Loading an FMU's binary in the C hosts (tests/fmi2_host.c, tests/fmi3_host.c): the library, a symbol of it
 * and its unloading, on Linux (dlopen; the path "-" is the host itself, for a build that links the FMU in) and
 * on Windows (LoadLibrary: the hosts cross-compiled by zig and run in wine, tests/test_native_win64.py,
 * tests/test_fmi3.py). Header-only, included once by each host. */
#ifndef HOST_LOADER_H
#define HOST_LOADER_H

#include <string.h>
#if defined(_WIN32)
#include <windows.h>
static void *open_library(const char *path) { return (void *)LoadLibraryA(path); }
static void *symbol(void *lib, const char *name) { return (void *)GetProcAddress((HMODULE)lib, name); }
static int close_library(void *lib) { return !FreeLibrary((HMODULE)lib); } /* 0: unloaded */
static const char *library_error(void) { return "LoadLibrary failed"; }
#else
#include <dlfcn.h>
static void *open_library(const char *path)
{
    return strcmp(path, "-") ? dlopen(path, RTLD_NOW | RTLD_LOCAL) : dlopen(NULL, RTLD_NOW);
}
static void *symbol(void *lib, const char *name) { return dlsym(lib, name); }
static int close_library(void *lib) { return dlclose(lib); } /* 0: unloaded */
static const char *library_error(void) { return dlerror(); }
#endif

#endif
