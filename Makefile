# consph: thin driver over CMake. `make demo` and `make check` do their own set-up.
BUILD      ?= build
ASAN_BUILD ?= build-asan
JOBS       ?= $(shell nproc 2>/dev/null || echo 2)
PREFIX     ?= /usr/local
CMAKE_ARGS ?=

.PHONY: all deps configure check demo asan bench install format format-check clean fuzz

all: $(BUILD)/consph

deps:
	@bash scripts/deps.sh

$(BUILD)/CMakeCache.txt: | deps
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release -DCMAKE_INSTALL_PREFIX=$(PREFIX) $(CMAKE_ARGS)

configure: $(BUILD)/CMakeCache.txt

$(BUILD)/consph: $(BUILD)/CMakeCache.txt FORCE
	cmake --build $(BUILD) -j $(JOBS)

check: $(BUILD)/consph
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

demo: $(BUILD)/consph
	bash scripts/demo.sh $(BUILD)/consph

# Without MPI (docs/mpi.md): OpenMPI's run-time keeps allocations to exit that LeakSanitizer
# reports; the multi-rank tests skip there.
asan: deps
	cmake -S . -B $(ASAN_BUILD) -DCMAKE_BUILD_TYPE=Debug -DCMAKE_C_FLAGS_DEBUG="-g -O1" -DCONSPH_SANITIZE=ON -DCONSPH_MPI=OFF $(CMAKE_ARGS)
	cmake --build $(ASAN_BUILD) -j $(JOBS)
	cd $(ASAN_BUILD) && ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
	  CONSPH_SANITIZED=1 ctest --output-on-failure -j $(JOBS)

bench: $(BUILD)/consph
	bash scripts/bench.sh $(BUILD)

install: $(BUILD)/consph
	cmake --install $(BUILD) --prefix $(PREFIX)

format:
	clang-format -i $$(git ls-files '*.c' '*.h')

format-check:
	clang-format --dry-run --Werror $$(git ls-files '*.c' '*.h')

# libFuzzer targets of the particle readers, the CLI option parsers and the study-file parser
# (fuzz/fuzz_*.c), built with clang's fuzzer, ASan and UBSan over the whole library and the CLI
# parser (compiled once into $(FUZZ_BUILD)/obj; the CLI's options reach the layout cache, the
# study parser's validation the whole library), then run one after the other for FUZZ_TIME
# seconds each
# from the seed corpus fuzz/corpus/<target>/. New inputs go to $(FUZZ_BUILD)/corpus-<target>/;
# a crash stops the run and leaves $(FUZZ_BUILD)/crash-<target>-*: copy it into
# fuzz/regressions/<target>/, where `make check` replays it from then on.
FUZZ_BUILD   ?= build-fuzz
FUZZ_TIME    ?= 60
FUZZ_CC      ?= clang
FUZZ_TARGETS ?= csv vtu inflate cli study
FUZZ_FLAGS   ?= -g -O1 -std=c11 -D_DEFAULT_SOURCE -fsanitize=fuzzer,address,undefined \
                -fno-sanitize-recover=undefined -Iinclude -Isrc -Iapps
FUZZ_SOURCES  = $(wildcard src/*/*.c src/*/*/*.c) apps/cli.c

fuzz:
	@command -v $(FUZZ_CC) >/dev/null || { echo "make fuzz needs clang with libFuzzer (Debian: clang, libclang-rt-dev)" >&2; exit 1; }
	@rm -rf $(FUZZ_BUILD)/obj && mkdir -p $(FUZZ_BUILD)/obj
	@echo "compiling $(words $(FUZZ_SOURCES)) sources into $(FUZZ_BUILD)/obj"
	@printf '%s\n' $(FUZZ_SOURCES) | xargs -P $(JOBS) -I{} sh -c \
	  'o=$(FUZZ_BUILD)/obj/$$(printf %s "$$1" | tr / _).o; $(FUZZ_CC) $(FUZZ_FLAGS) -c "$$1" -o "$$o"' sh {}
	@for t in $(FUZZ_TARGETS); do \
	  echo "building $(FUZZ_BUILD)/fuzz_$$t"; \
	  $(FUZZ_CC) $(FUZZ_FLAGS) fuzz/fuzz_$$t.c $(FUZZ_BUILD)/obj/*.o -lm -lz -o $(FUZZ_BUILD)/fuzz_$$t || exit 1; \
	done
	@for t in $(FUZZ_TARGETS); do \
	  mkdir -p $(FUZZ_BUILD)/corpus-$$t; \
	  dict=; [ -f fuzz/$$t.dict ] && dict=-dict=fuzz/$$t.dict; \
	  echo "fuzzing $$t for $(FUZZ_TIME) s"; \
	  $(FUZZ_BUILD)/fuzz_$$t $(FUZZ_BUILD)/corpus-$$t fuzz/corpus/$$t $$dict \
	    -max_total_time=$(FUZZ_TIME) -max_len=8192 -rss_limit_mb=2048 -timeout=10 \
	    -artifact_prefix=$(FUZZ_BUILD)/crash-$$t- -print_final_stats=1 \
	    >$(FUZZ_BUILD)/fuzz-$$t.log 2>&1 || { tail -40 $(FUZZ_BUILD)/fuzz-$$t.log; exit 1; }; \
	  grep -E '^stat::number_of_executed_units|^stat::peak_rss_mb' $(FUZZ_BUILD)/fuzz-$$t.log | sed "s/^/  $$t: /"; \
	done

clean:
	rm -rf $(BUILD) $(ASAN_BUILD)

FORCE:
