#!/usr/bin/env bash
# The test command's body (scripts/run.sh test, after the build): prepares what the real-data
# tests need, then runs every part — the C++ tests (library, CLI, service), the Python package,
# the console in headless Chromium, the service behind nginx with a server killed — and ends with
# a table: ran, passed, skipped. Nothing may be skipped (LINECLOUD_REQUIRE_ALL=1 makes a missing
# prerequisite a failure in every part); the command fails when any part does.
# The checks of CI's evaluation reports (EvalReport.*, EvalPrivacy.*, EvalColmap.*) belong to
# .ci/run's eval stage, which makes those reports; they are not part of this command.
set -uo pipefail
cd "$(dirname "$0")/.."
export LINECLOUD_REQUIRE_ALL=1
logs=build/test-logs
mkdir -p "$logs"
rows=() failed=0 t_all=$SECONDS

row() { rows+=("$(printf '| %-38s | %-6s | %6s | %7s | %7s |' "$@")"); }
table() {
  echo "== the test command, part by part"
  printf '| %-38s | %-6s | %6s | %7s | %7s |\n' part result passed skipped seconds
  echo "|----------------------------------------|--------|--------|---------|---------|"
  printf '%s\n' "${rows[@]}"
  echo "total $((SECONDS - t_all)) s; $([ $failed -eq 0 ] && echo "every part passed, none skipped" || echo "FAILED")"
}
trap table EXIT

t0=$SECONDS
if bash scripts/prepare_work.sh fountain-P11 >"$logs/prepare.log" 2>&1 &&
   bash scripts/prepare_work.sh Herz-Jesus-P8 >>"$logs/prepare.log" 2>&1; then
  row "real-data works (eval prepare)" ok - - $((SECONDS - t0))
else
  cat "$logs/prepare.log"; row "real-data works (eval prepare)" FAILED - - $((SECONDS - t0)); failed=1
  exit 1
fi
export LINECLOUD_FOUNTAIN_WORK="$PWD/build/eval/fountain-P11" LINECLOUD_HERZJESUS_WORK="$PWD/build/eval/Herz-Jesus-P8"

# C++: every CTest test but the evaluation-report checks. A fresh build has no CTest cost data:
# ctest would start the longest test (~90 s) last and leave a core idle meanwhile, so the long
# ones (their seconds measured in CI) are named to start first.
cost=build/Testing/Temporary/CTestCostData.txt
if [ ! -f "$cost" ]; then
  mkdir -p "$(dirname "$cost")"
  printf '%s 1 %s\n' Identity.VersionsOfARealMapGiveNothingBackBeyondNoise 130 \
    Identity.ARebuildFromNewFeaturesGivesNothingBack 80 Map.AnUpdateKeepsEveryReleasedLine 65 \
    Map.PhotosInAServedMapOut 25 Map.CtrlCInEachStageThenTheSameCommandEndsWithTheSameMap 21 \
    Map.KilledInEachStageThenTheSameCommandEndsWithTheSameMap 21 Map.ProjectsShareAKeyOnlyThroughTheirPhotos 17 \
    Guard.APlantedCacheLinkOrFifoIsNeverUsed 15 "Solvers/MinimalSolverTest.RecoversTheTruePoseAndSatisfiesItsEquations/m_p6L" 13 \
    DensityAttack.RecoversMostPointsOfADenseTexturedFacade 12 Resist.KeepsPointsTheAttackCannotRecover 12 \
    Hostile.DribblingClientsDoNotStarveOthers 11 Hostile.MixedTrafficSoakAnswersEveryoneRight 10 \
    Identity.AnUpdatedMapLocalizesHeldOutPhotosAsTheReleasedOneDid 10 \
    "Solvers/MinimalSolverTest.RecoversTheTruePoseAndSatisfiesItsEquations/p6L" 10 \
    SiftScaleSpace.ExtractorGivesVlFeatsFeaturesOnAnyThreadCount 9 > "$cost"
  echo "---" >> "$cost"
fi
t0=$SECONDS
ctest --test-dir build --output-on-failure -j2 -E '^(EvalReport|EvalPrivacy|EvalColmap)\.' 2>&1 | tee "$logs/ctest.log"
rc=${PIPESTATUS[0]}
total=$(sed -nE 's/.*tests passed, ([0-9]+) tests failed out of ([0-9]+).*/\2/p' "$logs/ctest.log")
bad=$(sed -nE 's/.*tests passed, ([0-9]+) tests failed out of ([0-9]+).*/\1/p' "$logs/ctest.log")
skipped=$(grep -c '(Skipped)' "$logs/ctest.log")
[ "$skipped" -eq 0 ] || rc=1
row "C++ (CTest: library, CLI, service)" "$([ $rc -eq 0 ] && echo ok || echo FAILED)" \
  "$(( ${total:-0} - ${bad:-0} - skipped ))/${total:-?}" "$skipped" $((SECONDS - t0))
[ $rc -eq 0 ] || failed=1

# Python: the package installed into a venv, its pytest suite.
t0=$SECONDS
bash scripts/python_test.sh 2>&1 | tee "$logs/python.log"
rc=${PIPESTATUS[0]}
summary=$(grep -E '^[0-9]+ (passed|failed)|[0-9]+ passed' "$logs/python.log" | tail -1)
passed=$(echo "$summary" | grep -oE '[0-9]+ passed' | cut -d' ' -f1)
skipped=$(echo "$summary" | grep -oE '[0-9]+ skipped' | cut -d' ' -f1)
[ "${skipped:-0}" -eq 0 ] || rc=1
row "Python (pip install into a venv, pytest)" "$([ $rc -eq 0 ] && echo ok || echo FAILED)" \
  "${passed:-0}" "${skipped:-0}" $((SECONDS - t0))
[ $rc -eq 0 ] || failed=1

# The console in headless Chromium against the real server.
t0=$SECONDS
{ bash scripts/build_web.sh && node web/tests/console.test.mjs; } 2>&1 | tee "$logs/web.log"
rc=${PIPESTATUS[0]}
row "browser (console, headless Chromium)" "$([ $rc -eq 0 ] && echo ok || echo FAILED)" \
  "$([ $rc -eq 0 ] && echo 1/1 || echo 0/1)" 0 $((SECONDS - t0))
[ $rc -eq 0 ] || failed=1

# Two servers behind deploy/nginx.conf, one killed mid-load.
t0=$SECONDS
bash scripts/fault_test.sh 2>&1 | tee "$logs/fault.log"
rc=${PIPESTATUS[0]}
row "service behind nginx, a server killed" "$([ $rc -eq 0 ] && echo ok || echo FAILED)" \
  "$([ $rc -eq 0 ] && echo 1/1 || echo 0/1)" 0 $((SECONDS - t0))
[ $rc -eq 0 ] || failed=1
exit $failed
