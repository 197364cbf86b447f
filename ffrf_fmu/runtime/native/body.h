/* The whole C runtime for its users above it (body.c, the FMU's C): the layout of a body and what
 * every layer offers, bottom up: so3 -> lu (dense LU) -> superelement -> factor (factorization by
 * structure) -> step -> accel -> advance -> body (creation, ownership: ffrf_runtime.h). Each .c file includes
 * the headers of the layers it calls, never one above. */
#ifndef FFRF_BODY_H
#define FFRF_BODY_H

#include "layout.h"
#include "so3.h"
#include "lu.h"
#include "factor.h"
#include "superelement.h"
#include "step.h"
#include "accel.h"
#include "advance.h"

#endif
