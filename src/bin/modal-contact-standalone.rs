//! The instrument as a standalone application (nice-plug's standalone
//! wrapper: JACK, ALSA or a dummy audio backend, MIDI input, the editor
//! window). Build with `cargo build --release --features standalone --bin
//! modal-contact-standalone`; `--help` lists the backend options. The
//! editor tests run it headless under Xvfb with `--backend dummy`.

fn main() {
    nice_plug::nice_export_standalone::<modal_contact::plugin::ModalContact>();
}
