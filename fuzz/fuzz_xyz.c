/* libFuzzer target: bsurf_read_buffer as a plain-text point list (.xyz,
 * .txt, .pts; corpus/fuzz_xyz). */
#define FUZZ_FORMAT BSURF_FORMAT_XYZ
#include "fuzz_reader.h"
