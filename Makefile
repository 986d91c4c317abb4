# The two commands of the README: `make demo` and `make test`. Both install missing system
# packages first (scripts/deps.sh). `make build`/`make demo` build the release profile, the binary
# users run and every speed figure comes from; `make test` the `checked` profile (optimised, with
# debug assertions, no LTO; see Cargo.toml), so CI builds everything once.

CARGO ?= cargo
export XDG_RUNTIME_DIR ?= /tmp/sphereclip-xdg
export CARGO_TERM_COLOR ?= never

.PHONY: demo test deps build fmt-check clippy unit wasm bench

deps:
	@bash scripts/deps.sh
	@mkdir -p $(XDG_RUNTIME_DIR) && chmod 0700 $(XDG_RUNTIME_DIR)

# the web viewer first: the binary embeds it (scripts/web.sh writes target/web/)
build: deps
	bash scripts/web.sh release
	$(CARGO) build --locked --release --bin sphereclip --bin sphereclip-gdal

demo: build
	./target/release/sphereclip demo --samples samples --out out

fmt-check:
	$(CARGO) fmt --all -- --check

clippy: deps
	$(CARGO) clippy --locked --all-targets -- -D warnings
	$(CARGO) clippy --locked --target wasm32-unknown-unknown -p sc_view_web -- -D warnings

unit: deps
	@if command -v cargo-nextest >/dev/null; then \
		$(CARGO) nextest run --locked --cargo-profile checked --no-fail-fast; \
	else \
		$(CARGO) test --locked --profile checked --no-fail-fast; \
	fi
	$(CARGO) test --locked --profile checked --doc

# the web viewer (viewer/web for wasm32, its glue and page in target/web/), before the tests
# build the binary that embeds it and the browser tests load
wasm: deps
	bash scripts/web.sh checked

test: deps fmt-check clippy wasm unit

bench: build
	bash bench/run.sh
