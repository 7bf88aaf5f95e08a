# Shortcuts for the scripts the README names.
.PHONY: demo test bench
demo:
	scripts/demo
test:
	scripts/test
bench:
	scripts/setup.sh
	cargo run --release -- bench
