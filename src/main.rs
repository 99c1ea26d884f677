use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = hexcue::cli::Cli::parse();
    match hexcue::app::run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("hexcue: error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
