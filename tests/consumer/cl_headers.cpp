// raykit/cl.hpp compiles in a consumer's translation unit under the consumer's warning flags.
#include <raykit/cl.hpp>

int raykit_consumer_cl_headers() { return raykit::kPacketWidth; }
