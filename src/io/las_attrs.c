/* LAS: the standard attributes of point formats 0-10 and the record sizes
 * (LAS 1.4 R15, tables 7-17), shared by the reader (las_read.c) and the
 * writer (las_write.c). */
#include "io/las.h"

const size_t io_las_record_size[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};

const io_las_attr_info io_las_attr[A_COUNT] = {{"intensity", BSURF_UINT16},
                                               {"return_number", BSURF_UINT8},
                                               {"number_of_returns", BSURF_UINT8},
                                               {"synthetic", BSURF_UINT8},
                                               {"key_point", BSURF_UINT8},
                                               {"withheld", BSURF_UINT8},
                                               {"overlap", BSURF_UINT8},
                                               {"scanner_channel", BSURF_UINT8},
                                               {"scan_direction_flag", BSURF_UINT8},
                                               {"edge_of_flight_line", BSURF_UINT8},
                                               {"classification", BSURF_UINT8},
                                               {"user_data", BSURF_UINT8},
                                               {"scan_angle_rank", BSURF_INT8},
                                               {"scan_angle", BSURF_INT16},
                                               {"point_source_id", BSURF_UINT16},
                                               {"gps_time", BSURF_FLOAT64},
                                               {"red", BSURF_UINT16},
                                               {"green", BSURF_UINT16},
                                               {"blue", BSURF_UINT16},
                                               {"nir", BSURF_UINT16},
                                               {"wave_packet_index", BSURF_UINT8},
                                               {"wave_offset", BSURF_FLOAT64},
                                               {"wave_size", BSURF_UINT32},
                                               {"wave_location", BSURF_FLOAT32},
                                               {"wave_xt", BSURF_FLOAT32},
                                               {"wave_yt", BSURF_FLOAT32},
                                               {"wave_zt", BSURF_FLOAT32}};

/* Which attributes format f has. */
int io_las_has_attr(int f, int a) {
  int modern = f >= 6;
  switch (a) {
  case A_OVERLAP:
  case A_CHANNEL:
  case A_ANGLE: return modern;
  case A_ANGLE_RANK: return !modern;
  case A_GPS: return f != 0 && f != 2;
  case A_RED:
  case A_GREEN:
  case A_BLUE: return f == 2 || f == 3 || f == 5 || f == 7 || f == 8 || f == 10;
  case A_NIR: return f == 8 || f == 10;
  case A_WP_INDEX:
  case A_WP_OFFSET:
  case A_WP_SIZE:
  case A_WP_LOCATION:
  case A_WP_XT:
  case A_WP_YT:
  case A_WP_ZT: return f == 4 || f == 5 || f == 9 || f == 10;
  default: return 1;
  }
}
