# Fails when a render/ library references an OpenGL function by name (an undefined gl* symbol):
# such a call binds to whichever of libOSMesa / libGL comes first in the link order (gl_proc.h).
foreach(library IN LISTS LIBRARIES)
  execute_process(COMMAND ${NM} --undefined-only ${library} OUTPUT_VARIABLE symbols
                  RESULT_VARIABLE result)
  if(NOT result EQUAL 0)
    message(FATAL_ERROR "nm failed on ${library}")
  endif()
  string(REGEX MATCHALL "[ \t]U gl[A-Z][A-Za-z0-9]*" direct "${symbols}")
  if(direct)
    message(FATAL_ERROR "${library} calls OpenGL by name (use GlApi):${direct}")
  endif()
endforeach()
message(STATUS "no direct OpenGL calls in ${LIBRARIES}")
