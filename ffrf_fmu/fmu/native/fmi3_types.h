/* The FMI 3.0 standard's types as published (fmi3FunctionTypes.h, with fmi3PlatformTypes.h), included without
 * the warning their preemption callbacks raise (declared without a prototype): for fmi3Functions.c (which then
 * includes the standard's fmi3Functions.h) and the C host and fuzzer of tests/. */
#ifndef FFRF_FMI3_TYPES_H
#define FFRF_FMI3_TYPES_H

#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wstrict-prototypes"
#endif
#include "fmi3FunctionTypes.h"
#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif

#endif
