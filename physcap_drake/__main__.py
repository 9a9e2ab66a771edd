"""`python -m physcap_drake`: the `physcap` command (see physcap_drake.launch)."""

from physcap_drake.launch import main

main()
