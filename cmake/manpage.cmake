# cmake -DBSURF=path/to/bootsurf -DVERSION=x.y.z -DOUT=bootsurf.1 -P manpage.cmake
# Writes the man page bootsurf(1): `bootsurf --help` as the description, then
# each command's `bootsurf COMMAND --help` (the commands are read from the
# "Commands:" list of the first).
function(bsurf_help out)
  execute_process(COMMAND ${BSURF} ${ARGN} OUTPUT_VARIABLE text RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "manpage.cmake: '${BSURF} ${ARGN}' failed (${rc})")
  endif()
  set(${out} "${text}" PARENT_SCOPE)
endfunction()

# roff: backslashes escaped, a line starting with . or ' protected.
function(bsurf_roff out text)
  string(REPLACE "\\" "\\e" text "${text}")
  string(REGEX REPLACE "(^|\n)([.'])" "\\1\\\\&\\2" text "${text}")
  set(${out} "${text}" PARENT_SCOPE)
endfunction()

bsurf_help(main --help)
string(REGEX MATCH "Commands:\n(([ ]+[a-z]+[^\n]*\n)+)" _ "${main}")
string(REGEX MATCHALL "\n  [a-z]+ " names "\n${CMAKE_MATCH_1}")
bsurf_roff(main_roff "${main}")
set(page ".TH BOOTSURF 1 \"\" \"bootsurf ${VERSION}\" \"User Commands\"\n")
string(APPEND page ".SH NAME\nbootsurf \\- statistics for 3D point clouds: bootstrap test error, normals with confidence, denoising, features\n")
string(APPEND page ".SH DESCRIPTION\n.nf\n${main_roff}.fi\n.SH COMMANDS\n")
foreach(name ${names})
  string(STRIP "${name}" name)
  bsurf_help(text ${name} --help)
  bsurf_roff(text "${text}")
  string(APPEND page ".SS ${name}\n.nf\n${text}.fi\n")
endforeach()
string(APPEND page ".SH SEE ALSO\nThe library: bootsurf.h, pkg-config bootsurf, find_package(bootsurf) in CMake.\n")
file(WRITE ${OUT} "${page}")
