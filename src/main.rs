fn main() -> std::process::ExitCode {
    hexcue::run_cli()
}
