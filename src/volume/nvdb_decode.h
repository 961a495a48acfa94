// nvdb_decode.h: NanoVDB density grids of double or quantized values (Fp4, Fp8, Fp16, FpN) read
// as the float grid the device reads (nvdb_decode.cpp has the design note).
#pragma once
#include <nanovdb/util/GridHandle.h>

#include "volume/volume_detail.h"

namespace spectrack {
namespace volume_detail {

// Whether nvdb_decode reads grids of this value type.
bool nvdb_decodable(nanovdb::GridType t);
// The untrusted grid in src (its header checked by nvdb_read) validated and decoded into a float
// grid; throws through fail where it is damaged or a value cannot be a float.
nanovdb::GridHandle<nanovdb::HostBuffer> nvdb_decode(const nanovdb::GridHandle<nanovdb::HostBuffer>& src, const Entry& e,
                                                     const Fail& fail);

}  // namespace volume_detail
}  // namespace spectrack
