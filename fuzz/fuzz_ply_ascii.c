/* libFuzzer target: bsurf_read_buffer as a PLY file, seeded with ascii PLY
 * (corpus/fuzz_ply_ascii, dictionary ply.dict). */
#define FUZZ_FORMAT BSURF_FORMAT_PLY
#include "fuzz_reader.h"
