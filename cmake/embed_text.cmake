# bloomref_embed_text(OUT FUNCTION NAMESPACE HEADER FILES...): writes OUT, a C++ source defining
# `const std::map<std::string, std::string>& NAMESPACE::FUNCTION()`, file name -> text, declared
# in HEADER (which OUT includes), from FILES at configure time. The configure step re-runs when a
# file's text changes. The GL path's shaders and the Vulkan path's use it.
function(bloomref_embed_text out function namespace header)
  set(text "// Generated at configure time; do not edit.\n#include \"${header}\"\n\nnamespace ${namespace} {\nconst std::map<std::string, std::string>& ${function}() {\n  static const std::map<std::string, std::string> s = {\n")
  foreach(f ${ARGN})
    get_filename_component(name ${f} NAME)
    file(READ ${f} body)
    string(APPEND text "    {\"${name}\", R\"glsl(${body})glsl\"},\n")
  endforeach()
  string(APPEND text "  };\n  return s;\n}\n}  // namespace ${namespace}\n")
  set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${ARGN})
  file(WRITE ${out}.tmp "${text}")
  configure_file(${out}.tmp ${out} COPYONLY)
endfunction()
