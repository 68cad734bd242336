// The whole public API in one include (the stages' headers, in pipeline order, are also usable
// alone: hgdeform/io/, graph/, field/, cluster/, multires/, solve/, interp/, deformer/, app/; util/phase.h).
// The typed PCL entry, hgdeform/pcl.h, is left to those who want its templates.
#pragma once

#include "hgdeform/app/memory.h"
#include "hgdeform/app/report.h"
#include "hgdeform/app/runner.h"
#include "hgdeform/app/scenario.h"
#include "hgdeform/app/session.h"
#include "hgdeform/deformer/deformer.h"
#include "hgdeform/io/cleanup.h"
#include "hgdeform/io/fields.h"
#include "hgdeform/io/io.h"
#include "hgdeform/version.h"
