use clap::Parser;

fn main() {
    // candle's elementwise ops run on its own spinning thread pool, which fights the fused
    // LSTM's rayon threads for the cores: with other work on the machine a training step
    // measured 1.2-1.4x faster with candle's pool off (7-10% slower on an idle machine;
    // docs/BENCHMARKS.md). Set before any thread starts.
    if std::env::var_os("CANDLE_NUM_THREADS").is_none() {
        std::env::set_var("CANDLE_NUM_THREADS", "1");
    }
    let cli = glocal::cli::Cli::parse();
    if let Err(e) = glocal::cli::run(cli) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
