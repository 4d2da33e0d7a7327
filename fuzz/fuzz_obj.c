/* libFuzzer target: bsurf_read_buffer as a Wavefront OBJ file
 * (corpus/fuzz_obj, dictionary obj.dict). */
#define FUZZ_FORMAT BSURF_FORMAT_OBJ
#include "fuzz_reader.h"
