// SPDX-License-Identifier: Apache-2.0
// Rays in, hits out, as NumPy .npy files (format version 1.0/2.0, little-endian, C order).
// Input: a 2-D float64 or float32 array of shape (n, 6), (n, 8) or (n, 9): columns
// ox,oy,oz,dx,dy,dz[,tmin,tmax[,id]]. Output: a 1-D structured array with the CSV's fields
// (id, hit, t, px..pz as <f8, nx..snz, u, v as <f4, object and material as fixed-width byte
// strings, primitive as <i8 with -1 for a miss; with a field mask, id, hit and the asked fields'
// columns); np.load() reads it as is.
#pragma once

#include <string>

#include "rays/ray_table.h"
#include "rays/rays_error.h"

namespace tessera::rays {

// Throw RaysError naming the file and what is wrong with it.
RayTable read_rays_npy(const std::string& path);
void write_hits_npy(const std::string& path, const RayTable& rays, const HitTable& hits);

}  // namespace tessera::rays
