use clap::Parser;

fn main() {
    let cli = glocal::cli::Cli::parse();
    if let Err(e) = glocal::cli::run(cli) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
