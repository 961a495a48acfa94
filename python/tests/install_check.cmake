# install_check.cmake: `cmake --install` of the build into a fresh prefix, then the installed
# package imported (from outside the build) and a one-sample render. -DBUILD=<build folder>
# -DPY=<python> -DOUT=<scratch folder>.
file(REMOVE_RECURSE ${OUT})
execute_process(COMMAND ${CMAKE_COMMAND} --install ${BUILD} --prefix ${OUT} RESULT_VARIABLE rc OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "cmake --install failed (${rc})")
endif()
file(GLOB_RECURSE init ${OUT}/__init__.py)
if(NOT init)
  message(FATAL_ERROR "no spectrack/__init__.py under ${OUT}")
endif()
get_filename_component(pkg ${init} DIRECTORY)
get_filename_component(site ${pkg} DIRECTORY)
execute_process(COMMAND ${CMAKE_COMMAND} -E env PYTHONPATH=${site} ${PY} -c
  "import spectrack; assert spectrack.__file__.startswith('${site}'); s = spectrack.load_dict({'format': 'spectrack-scene/1', 'film': {'width': 4, 'height': 3, 'spp': 1}, 'lights': [{'type': 'environment'}]}); assert s.render().rgb.shape == (3, 4, 3)"
  WORKING_DIRECTORY ${OUT} RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the installed spectrack did not import and render (${rc})")
endif()
