use clap::Parser;

fn main() {
    // candle's elementwise ops run on its own spinning thread pool, which here fights the
    // rayon pool of gemm and the fused LSTM for the same cores: a training step measured up to
    // 1.9x faster with candle's pool off (docs/BENCHMARKS.md). Set before any thread starts.
    if std::env::var_os("CANDLE_NUM_THREADS").is_none() {
        std::env::set_var("CANDLE_NUM_THREADS", "1");
    }
    let cli = glocal::cli::Cli::parse();
    if let Err(e) = glocal::cli::run(cli) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
