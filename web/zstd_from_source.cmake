# zstd compiled from a source tree (FACEMORPH_ZSTD_SOURCE_DIR): Debian's own source of the libzstd
# the native build links (web/fetch-zstd-source.sh), for the WebAssembly build, where no libzstd.a
# exists for the target. The decompressor is what the decoder uses; the compressor is compiled too
# because format/zstd_frame.cpp names it (the linker drops it from the module: nothing calls it).
# No assembly (the x86-64 Huffman loop), no threads, no legacy formats: what the container needs.
file(GLOB facemorph_zstd_compress_sources ${FACEMORPH_ZSTD_SOURCE_DIR}/lib/compress/*.c)
file(GLOB facemorph_zstd_sources
  ${FACEMORPH_ZSTD_SOURCE_DIR}/lib/common/*.c
  ${facemorph_zstd_compress_sources}
  ${FACEMORPH_ZSTD_SOURCE_DIR}/lib/decompress/*.c)
# As nothing in the module is the compressor, it is compiled at -O0: CI builds the module afresh
# inside the web tests, and at -O3 the compressor was the costliest part of zstd's compile. The
# module is byte for byte the one the compressor at -O3 gives (web/dist/facemorph_wasm.wasm, cmp).
set_source_files_properties(${facemorph_zstd_compress_sources} PROPERTIES COMPILE_OPTIONS -O0)
if(NOT facemorph_zstd_sources)
  message(FATAL_ERROR "facemorph: no zstd sources under FACEMORPH_ZSTD_SOURCE_DIR=${FACEMORPH_ZSTD_SOURCE_DIR} (web/fetch-zstd-source.sh)")
endif()
enable_language(C)
add_library(facemorph_zstd STATIC ${facemorph_zstd_sources})
target_include_directories(facemorph_zstd PUBLIC ${FACEMORPH_ZSTD_SOURCE_DIR}/lib)
target_compile_definitions(facemorph_zstd PRIVATE ZSTD_DISABLE_ASM ZSTD_MULTITHREAD=0 ZSTD_LEGACY_SUPPORT=0)
# The name format/ links, as zstd's own CMake package calls it.
add_library(zstd::libzstd_shared ALIAS facemorph_zstd)
