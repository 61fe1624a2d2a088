# SPDX-License-Identifier: Apache-2.0
# Which way the project's modules may depend on each other, checked on every
# #include of every C/C++ source (CTest: layering.includes):
#   cmake -DSOURCE_DIR=<source tree> -P tests/layering/includes.cmake
# Fails naming file:line and the forbidden arrow. docs/architecture.md
# ("Allowed includes") states the same table; change both together.
cmake_minimum_required(VERSION 3.25)

if(NOT SOURCE_DIR)
  get_filename_component(SOURCE_DIR "${CMAKE_CURRENT_LIST_DIR}/../.." ABSOLUTE)
endif()

# "includer: what it may include". The includer is one file, or a folder and
# what is under it unless a longer row names it. What it may include is a
# module (a folder row of this table, so "firmware" is firmware/'s own files
# and not firmware/daemon/), one file, or * for anything.
# common/ is the shared vocabulary (fringe set, phase source, camera name): it
# depends on nothing, and every module may use it.
set(allowed
  "common: common"
  "algo: algo common"
  "formats: formats common"
  "drivers: drivers common"
  "firmware: firmware algo formats drivers common"
  "firmware/daemon: firmware/daemon firmware algo formats drivers common"
  # The daemon program joins the service and its HTTP API.
  "firmware/daemon/cylscand.cpp: firmware/daemon firmware/http firmware algo formats drivers common"
  "firmware/http: firmware/http firmware/daemon/head_service.hpp common"
  "tools: tools firmware algo formats drivers common"
  "bench: bench algo common"
  "fuzz: *"
  "tests: *")

set(rule_keys "")
set(module_keys "")
foreach(row IN LISTS allowed)
  if(NOT row MATCHES "^([^: ]+): *(.*)$")
    message(FATAL_ERROR "includes.cmake: bad row '${row}'")
  endif()
  set(key "${CMAKE_MATCH_1}")
  string(REPLACE " " ";" targets "${CMAKE_MATCH_2}")
  list(APPEND rule_keys "${key}")
  set("allow_${key}" "${targets}")
  if(IS_DIRECTORY "${SOURCE_DIR}/${key}")
    list(APPEND module_keys "${key}")
  elseif(NOT EXISTS "${SOURCE_DIR}/${key}")
    message(FATAL_ERROR "includes.cmake: the row '${key}' names nothing in ${SOURCE_DIR}")
  endif()
endforeach()

# The longest key of KEYS that is PATH or a folder above it (empty: none).
function(longest_key out path keys)
  set(best "")
  set(best_length 0)
  foreach(key IN LISTS keys)
    if(path STREQUAL key OR path MATCHES "^${key}/")
      string(LENGTH "${key}" length)
      if(length GREATER best_length)
        set(best "${key}")
        set(best_length ${length})
      endif()
    endif()
  endforeach()
  set(${out} "${best}" PARENT_SCOPE)
endfunction()

# Every C/C++ source under the tree's folders, but not build trees (their
# sysroots and generated files), hidden folders or node_modules.
file(GLOB top LIST_DIRECTORIES true RELATIVE "${SOURCE_DIR}" "${SOURCE_DIR}/*")
set(sources "")
foreach(dir IN LISTS top)
  if(NOT IS_DIRECTORY "${SOURCE_DIR}/${dir}" OR dir MATCHES "^(build.*|out|\\..*)$")
    continue()
  endif()
  file(GLOB_RECURSE found RELATIVE "${SOURCE_DIR}" "${SOURCE_DIR}/${dir}/*.cpp" "${SOURCE_DIR}/${dir}/*.cc"
       "${SOURCE_DIR}/${dir}/*.c" "${SOURCE_DIR}/${dir}/*.hpp" "${SOURCE_DIR}/${dir}/*.h")
  list(FILTER found EXCLUDE REGEX "/node_modules/")
  list(APPEND sources ${found})
endforeach()
list(SORT sources)

set(violations "")
set(checked 0)
foreach(file IN LISTS sources)
  longest_key(rule "${file}" "${rule_keys}")
  if(NOT rule)
    list(APPEND violations "${file}: no row of the table says what it may include")
    continue()
  endif()
  get_filename_component(file_dir "${file}" DIRECTORY)
  file(READ "${SOURCE_DIR}/${file}" rest)
  # Each match starts at a newline, so the first line needs one before it.
  set(rest "\n${rest}")
  set(line 0)
  while(TRUE)
    string(REGEX MATCH "\n[ \t]*#[ \t]*include[ \t]*[\"<][^\">\n]*[\">]" match "${rest}")
    if(NOT match)
      break()
    endif()
    string(FIND "${rest}" "${match}" at)
    string(SUBSTRING "${rest}" 0 ${at} before)
    string(LENGTH "${before}" before_length)
    string(REPLACE "\n" "" before "${before}")
    string(LENGTH "${before}" stripped_length)
    math(EXPR line "${line} + ${before_length} - ${stripped_length} + 1")
    string(LENGTH "${match}" match_length)
    math(EXPR next "${at} + ${match_length}")
    string(SUBSTRING "${rest}" ${next} -1 rest)

    string(REGEX REPLACE "^.*([\"<])([^\">]*)[\">]$" "\\1;\\2" parts "${match}")
    list(GET parts 0 bracket)
    list(GET parts 1 name)
    # As the compiler looks: "x" beside the including file first, then the
    # tree's root (every target's include path); <x> only at the root. A
    # header found in neither is not the project's.
    set(target "")
    if(bracket STREQUAL "\"" AND EXISTS "${SOURCE_DIR}/${file_dir}/${name}")
      set(target "${file_dir}/${name}")
    elseif(EXISTS "${SOURCE_DIR}/${name}" AND NOT IS_DIRECTORY "${SOURCE_DIR}/${name}")
      set(target "${name}")
    endif()
    if(NOT target)
      continue()
    endif()
    cmake_path(NORMAL_PATH target)
    math(EXPR checked "${checked} + 1")

    longest_key(target_module "${target}" "${module_keys}")
    set(ok FALSE)
    foreach(allowed_target IN LISTS "allow_${rule}")
      if(allowed_target STREQUAL "*" OR allowed_target STREQUAL target
         OR (target_module AND allowed_target STREQUAL target_module))
        set(ok TRUE)
        break()
      endif()
    endforeach()
    if(NOT ok)
      if(target_module)
        set(to "${target_module}")
      else()
        set(to "${target}")
      endif()
      string(REGEX REPLACE "^.*#[ \t]*include[ \t]*" "" spelled "${match}")
      list(JOIN "allow_${rule}" ", " may)
      list(APPEND violations
           "${file}:${line}: ${rule} -> ${to} (#include ${spelled}), but ${rule} may include only: ${may}")
    endif()
  endwhile()
endforeach()

list(LENGTH sources file_count)
if(violations)
  list(LENGTH violations violation_count)
  list(JOIN violations "\n" text)
  message("${text}")
  message(FATAL_ERROR "layering: ${violation_count} forbidden include(s) in ${file_count} files "
                      "(the allowed directions: tests/layering/includes.cmake, docs/architecture.md)")
endif()
message(STATUS "layering: ${checked} project includes in ${file_count} files, all in allowed directions")
