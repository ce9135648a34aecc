// SPDX-License-Identifier: Apache-2.0
// Rays in, hits out, as CSV with a header row. Input columns (any order, names as in the
// header): ox,oy,oz,dx,dy,dz required, tmin,tmax,id optional; other columns are refused, so a
// typo is not silently ignored. Output: id (if the input had ids),hit,t,px,py,pz,nx,ny,nz,
// snx,sny,snz,u,v,object,primitive,material (occlusion queries: id,hit), or with a field mask
// (HitTable::fields) id,hit and the asked fields' columns, in that order. Numbers are written
// with enough digits to read back the same float/double bits.
#pragma once

#include <iosfwd>
#include <string>

#include "rays/ray_table.h"
#include "rays/rays_error.h"

namespace tessera::rays {

// Throws RaysError naming `source`, the line and the column of a malformed value.
RayTable read_rays_csv(std::istream& in, const std::string& source);
void write_hits_csv(std::ostream& out, const RayTable& rays, const HitTable& hits);

}  // namespace tessera::rays
