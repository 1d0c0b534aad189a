"""The command line as a whole (cli.main): unknown commands and bad arguments are one-line
errors; --help lists every command without importing one."""

import pytest


@pytest.mark.parametrize(
    "args,needle",
    [
        (["simulate", "--sides", "2"], "--sides"),
        (["simulate", "--side-length", "-1"], "--side-length"),
        (["simulate", "--side-length", "nan"], "--side-length"),
        (["simulate", "--runs", "0"], "--runs"),
        (["simulate", "--direction", "up"], "--direction"),
        (["simulate", "--seed", "x"], "--seed"),
        (["calibrate"], "RUNS.csv"),
        (["calibrate", "r.csv", "--method", "magic"], "--method"),
        (["frobnicate"], "frobnicate"),
    ],
)
def test_bad_arguments(cli, args, needle):
    cli(*args).expect_error(needle)


def test_help_is_complete_and_imports_no_command_module():
    # 'odocal --help' lists every command with its line without importing any command module
    # (nor numpy); every module still builds its own parser under its name
    import subprocess
    import sys

    from odocal.cli.main import COMMANDS, build_parser

    code = (
        "import sys, contextlib, io\n"
        "from odocal.cli.main import main\n"
        "buf = io.StringIO()\n"
        "with contextlib.redirect_stdout(buf):\n"
        "    try:\n"
        "        main(['--help'])\n"
        "    except SystemExit:\n"
        "        pass\n"
        "print(buf.getvalue())\n"
        "print('LOADED', sorted(m for m in sys.modules if m.startswith('odocal.cli.') "
        "or m == 'numpy'))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout
    assert all(name in out for name in COMMANDS)
    assert "LOADED ['odocal.cli.main']" in out
    sub = next(a for a in build_parser()._actions if hasattr(a, "choices") and a.choices)
    assert list(sub.choices) == list(COMMANDS)


def test_no_arguments_print_the_help_and_exit_2(cli):
    """'odocal' alone prints the help (every command listed) on stdout, not an error line, and
    exits 2: no command ran (a script calling it without a command notices)."""
    from odocal.cli.main import COMMANDS

    status, out, err = cli()
    assert status == 2 and err == ""
    assert out.startswith("usage: odocal") and all(name in out for name in COMMANDS)


def test_a_file_name_with_a_line_break_gives_a_one_line_error(cli, tmp_path):
    # issue 20, hostile inputs: the file name was printed raw, so the error took two lines
    name = tmp_path / "a\nb\u2028c.csv"
    status, out, err = cli("calibrate", name, "--robot", "paper-fig5")
    assert status == 2 and out == ""
    assert err.count("\n") == 1 and "\u2028" not in err
    assert err.startswith("odocal: error: '") and "a\\nb\\u2028c.csv': no such file" in err
