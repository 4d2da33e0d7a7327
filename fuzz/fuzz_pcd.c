/* libFuzzer target: bsurf_read_buffer as PCD (corpus/fuzz_pcd). */
#define FUZZ_FORMAT BSURF_FORMAT_PCD
#include "fuzz_reader.h"
