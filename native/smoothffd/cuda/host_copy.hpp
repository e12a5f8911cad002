// Copies of the device's output into host memory (the evaluators' copy back).
#pragma once

#include <cuda_runtime_api.h>

#include <vector>

#include "smoothffd/cuda/device_memory.hpp"

namespace sffd {
namespace cuda_impl {

struct HostCopy {
  void* dst;
  const void* src;
  size_t bytes;
};

// Copies device bytes to host memory behind the work queued on `stream`: straight into a
// page-locked destination; into any other through the pinned staging buffer in 1 MiB chunks,
// host threads copying each chunk on as soon as its transfer has finished (bus and host copy
// overlap, so a pageable destination costs about one chunk's host copy more than the
// transfer; 4 MiB chunks left a 0.4 ms tail on the H100 machine). Event `from` of `events`
// must be recorded already; events after it are used. Returns the ms from event `from` to the
// end of the transfers.
float copy_to_host(const std::vector<HostCopy>& segs, cudaStream_t stream, Events& events, size_t from,
                   PinnedBuffer& staging);

}  // namespace cuda_impl
}  // namespace sffd
